"""The IK core's datapath (:class:`~ik5r.hdl.ik_core.IKCore`): ONE
:class:`~ik5r.hdl.datapath.Datapath` composed, group by group, from the blocks' chains (atan2,
the rotation's micro-rotations, the arc cosine's parts, the square root, the multipliers) and
small glue stages. Each group is a method of :class:`_CoreStages`; the values a later group needs
travel in the :class:`~ik5r.hdl.stash.Stash`, through the handle the earlier group returns.
"""

from __future__ import annotations

from amaranth.hdl import Cat, Mux, signed

from ik5r.core import status as S
from ik5r.core.fxconfig import Constants

from .acos import Acos
from .chains import add_selecting, append_chains, concat, namespaced
from .datapath import Datapath
from .expr import drop, rshift_round, saturate
from .ik_orientation import (
    orientation_flag,
    orientation_operands,
    orientation_specs,
    orientation_sums,
    orientation_terms,
)
from .ik_steps import (
    add_c3,
    add_c3_complements,
    atan2_chain,
    const_mul_operand,
    flag,
    opposite,
    rotate_const_chain,
    wrap_compares,
    wrapped,
)
from .products import add_products
from .sqrt import add_isqrt, fit
from .stash import Stash

__all__ = ["core_datapath"]


def core_datapath(words: Constants, stash: Stash, tag: bool, compact: bool, adders) -> Datapath:
    """The IK on the internal format ``k = words.internal`` (the words themselves unless the config
    has ``ik.internal_guard_bits``); the inputs arrive shifted up (:meth:`IKCore._inputs`) and the
    joints leave rounded back to words."""
    core = _CoreStages(words, stash, compact, adders)
    pose = core.select(tag)
    core.base_joint(pose)
    base = core.base_rotation()
    core.dot_products(pose)
    roll = core.pitch_and_roll(pose)
    core.wrist_centre(pose, base)
    gamma = core.elbow()
    core.beta()
    core.joints(pose, base, roll, gamma)
    if tag:
        stash.take(core.dp, pose, "tag")
    core.wrap_q4()
    core.round_joints()
    stash.check_taken()
    return core.dp


class _CoreStages:
    """The stage groups of the core, appended to :attr:`dp` in the order of the model."""

    def __init__(self, words: Constants, stash: Stash, compact: bool, adders):
        self.words, self.k, self.stash = words, words.internal, stash
        self.compact, self.adders = compact, adders
        c = self.k.cfg
        self.width, self.fu, self.nearest = c.width, c.frac_unit, c.round_nearest
        self.word = signed(c.width)
        self.products = "sequential" if compact else "parallel"
        self.dp = Datapath("ik", products=self.products, share_units=compact, adders=adders)

    def chain(self, name: str) -> Datapath:
        """A scratch chain with the core's multiplier schedule and adders."""
        return Datapath(name, products=self.products, adders=self.adders)

    def selecting(self, name, compares, fn, dp=None):
        add_selecting(self.dp if dp is None else dp, name, compares, fn, registered=not self.compact)

    def select(self, tag: bool):
        """Stage 0: joint-1 vector (the point, or the approach on the base axis); d1 - pz. The
        pose's other fields wait in the stash (the returned handle)."""
        k = self.k

        def select(s):
            px, py = s["px"], s["py"]
            on_axis = (px == 0) & (py == 0)
            out = drop(s, "px", "py", "pz")
            out.update({"T1__y": Mux(on_axis, s["ay"], py), "T1__x": Mux(on_axis, s["ax"], px),
                        "RH__px": px, "RH__py": py, "dz": k.d1_l - s["pz"]})
            return out

        self.dp.add("select", select)
        return self.stash.put(self.dp, "dz", "ax", "ay", "az", "nx", "ny", "nz", "ox", "oy", "oz",
                              "roll", "q5d", "back", "down", *(("tag",) if tag else ()))

    def base_joint(self, pose):
        """theta1 = atan2(py, px) || rho = sat(isqrt(px^2 + py^2)) (2W-bit radicand: the model's
        64-bit one has only zero bit pairs above px^2 + py^2 < 2**(2W-1)); then q1 (branch) and
        r - a1."""
        k, width, word = self.k, self.width, self.word
        rho = self.chain("rho")
        add_products(rho, "sq", [(lambda s: s["px"], word, (lambda s: s["px"], word), "xx"),
                                 (lambda s: s["py"], word, (lambda s: s["py"], word), "yy")],
                     drop_keys=("px", "py"))
        rho.add("sum", lambda s: dict(drop(s, "xx", "yy"), sq_rad=fit(s["xx"] + s["yy"], 2 * width)))
        add_isqrt(rho, bits=2 * width, nearest=self.nearest, root="root")

        def rho_sat(s):
            value, sat = saturate(s["root"], width)
            return dict(drop(s, "root"), rho=value, sat=sat)

        rho.add("sat", rho_sat)
        append_chains(self.dp, "p1", atan2_chain(k, "T1__", zero=True, adders=self.adders),
                      namespaced(rho, "RH__"))
        self.stash.take(self.dp, pose, "back")

        def joint1(s, flags):
            theta, back, rho_l = s["T1__angle"], s["back"], s["RH__rho"]
            q1 = Mux(back, opposite(theta, flags["positive"], k), theta)
            out = drop(s, "T1__angle", "T1__zero", "RH__rho", "RH__sat", "back")
            out.update(q1=q1, C1__angle=q1, xa=Mux(back, -k.a1_l - rho_l, rho_l - k.a1_l),
                       st=flag(s["T1__zero"], S.SINGULAR_BASE) | flag(s["RH__sat"], S.SATURATED))
            return out

        self.selecting("joint1", {"positive": lambda s: s["T1__angle"] > 0}, joint1)

    def base_rotation(self):
        """(c1, s1) = rotate((1, 0), q1); q1 and r - a1 wait in the stash (the returned handle)."""
        base = self.stash.put(self.dp, "q1", "xa")
        append_chains(self.dp, "c1", rotate_const_chain(self.k, "C1__", (self.k.one_u, 0),
                                                        skewed=not self.compact, adders=self.adders))
        return base

    def dot_products(self, pose):
        """a_radial = a . (c1, s1); s5, c5 = n, o . (s1, -c1): six products, sums, rounding; the
        orientation checks' products beside them."""
        words, word, width, fu, nearest = self.words, self.word, self.width, self.fu, self.nearest
        self.stash.take(self.dp, pose, "ax", "ay", "az", "nx", "ny", "nz", "ox", "oy", "oz", "roll")
        c1_of, s1_of = (lambda s: s["C1__x"]), (lambda s: s["C1__y"])
        add_products(self.dp, "dot", orientation_specs(words) + [
            (lambda s: s["ax"], word, (c1_of, word), "pa1"), (lambda s: s["ay"], word, (s1_of, word), "pa2"),
            (lambda s: s["nx"], word, (s1_of, word), "pn1"), (lambda s: s["ny"], word, (c1_of, word), "pn2"),
            (lambda s: s["ox"], word, (s1_of, word), "po1"), (lambda s: s["oy"], word, (c1_of, word), "po2"),
        ], parallel=lambda s: {"st": s["st"] | flag(s["C1__saturated"], S.SATURATED),
                               **orientation_operands(s, words)},
            drop_keys=("ax", "ay", "nx", "ny", "nz", "ox", "oy", "oz", "C1__x", "C1__y", "C1__saturated"))
        self.dp.add("dot_sum", lambda s: dict(drop(orientation_sums(s), "pa1", "pa2", "pn1", "pn2", "po1", "po2"),
                                              da=s["pa1"] + s["pa2"], dn=s["pn1"] - s["pn2"],
                                              do=s["po1"] - s["po2"]))
        self.dp.add("dot_round", lambda s: dict(orientation_terms(s, words),
                                                **{key: rshift_round(s[key], fu, nearest)
                                                   for key in ("da", "dn", "do")}))

        def dot_saturate(s):
            a_rad, sat_a = saturate(s["da"], width)
            s5, sat_s = saturate(s["dn"], width)
            c5, sat_c = saturate(s["do"], width)
            s, orientation = orientation_flag(s, words)
            out = drop(s, "da", "dn", "do", "az")
            out.update({"PT__y": a_rad, "PT__x": s["az"], "Q5__y": s5, "Q5__x": c5,
                        "st": s["st"] | orientation | flag(sat_a | ((sat_s | sat_c) & s["roll"]), S.SATURATED)})
            return out

        self.dp.add("dot_sat", dot_saturate)

    def pitch_and_roll(self, pose):
        """pitch = atan2(a_radial, az) || roll = atan2(s5, c5); phi, q5. phi and q5 wait in the
        stash (the returned handle)."""
        k, adders = self.k, self.adders
        append_chains(self.dp, "p3", atan2_chain(k, "PT__", zero=True, adders=adders),
                      atan2_chain(k, "Q5__", zero=True, adders=adders))
        self.stash.take(self.dp, pose, "q5d")

        def pitch(s, flags):
            phi = opposite(s["PT__angle"], flags["positive"], k)
            roll = s["roll"]
            out = drop(s, "PT__angle", "PT__zero", "Q5__angle", "Q5__zero", "roll", "q5d")
            out.update(phi=phi, R2__angle=phi, q5=Mux(roll, s["Q5__angle"], s["q5d"]),
                       st=s["st"] | flag(s["PT__zero"] | (roll & s["Q5__zero"]), S.INVALID))
            return out

        self.selecting("pitch", {"positive": lambda s: s["PT__angle"] > 0}, pitch)
        return self.stash.put(self.dp, "phi", "q5")

    def wrist_centre(self, pose, base):
        """(xw, yw) = sat((r - a1, d1 - pz) - R(phi) (a4, d5))."""
        k, width = self.k, self.width
        append_chains(self.dp, "r2", rotate_const_chain(k, "R2__", (k.a4_l, k.d5_l),
                                                        skewed=not self.compact, adders=self.adders))
        self.stash.take(self.dp, base, "xa")
        self.stash.take(self.dp, pose, "dz")
        self.dp.add("wrist", lambda s: dict(drop(s, "xa", "dz", "R2__x", "R2__y", "R2__saturated"),
                                            xwr=s["xa"] - s["R2__x"], ywr=s["dz"] - s["R2__y"],
                                            st=s["st"] | flag(s["R2__saturated"], S.SATURATED)))

        def wrist_saturate(s):
            xw, sat_x = saturate(s["xwr"], width)
            yw, sat_y = saturate(s["ywr"], width)
            out = drop(s, "xwr", "ywr")
            out.update({"GM__y": yw, "GM__x": xw, "EL__xw": xw, "EL__yw": yw,
                        "st": s["st"] | flag(sat_x | sat_y, S.SATURATED)})
            return out

        self.dp.add("wrist_sat", wrist_saturate)

    def elbow(self):
        """gamma = atan2(yw, xw) || c3 = clip(mul_const(clip(xw^2 + yw^2 - links), c3_from_l2)) and
        the first half of acos (sine by the square root); gamma waits in the stash (the returned
        handle) while the second half runs."""
        k, word = self.k, self.word
        el = self.chain("elbow")
        add_products(el, "sq", [(lambda s: s["xw"], word, (lambda s: s["xw"], word), "xx"),
                                (lambda s: s["yw"], word, (lambda s: s["yw"], word), "yy")],
                     drop_keys=("xw", "yw"))
        el.add("sum", lambda s: dict(drop(s, "xx", "yy"), d2=s["xx"] + s["yy"]))
        el.add("links", lambda s: dict(drop(s, "d2"), num=s["d2"] - k.links_sq_l2))
        limit = k.twice_a2a3_l2
        reach_limit = k.reach_limit_l2      # beyond +-limit by the reach tolerance: unreachable

        def reach(s, flags):
            num, over, under = s["num"], flags["over"], flags["under"]
            return dict(drop(s, "num"), unreach=flags["far_over"] | flags["far_under"],
                        numc=Mux(over, limit, Mux(under, -limit, num)))

        self.selecting("reach", {"over": lambda s: s["num"] > limit, "under": lambda s: s["num"] < -limit,
                                 "far_over": lambda s: s["num"] > reach_limit,
                                 "far_under": lambda s: s["num"] < -reach_limit}, reach, dp=el)
        if self.words.cfg.internal_guard_bits == 0:
            add_c3(el, k, limit, registered=not self.compact)
            acos = Acos.chain(k, self.products, adders=self.adders)
            first = "factors"
        else:
            add_c3_complements(el, k, limit, registered=not self.compact)
            acos = Acos.chain(k, self.products, radicand_bits=2 * self.fu + 4, adders=self.adders)
            first = "radicand"
        el.shapes.update(acos.shapes)
        el.stages.extend(acos.part(first, "atan2").stages)
        #: The arc cosine's second half (atan2(sine, c3)), run beside beta by :meth:`beta`.
        self.acos_tail = acos.part("atan2")
        append_chains(self.dp, "e1", atan2_chain(k, "GM__", zero=False, adders=self.adders),
                      namespaced(el, "EL__"))

        def after_sqrt(s):
            out = drop(s, "EL__sine", "GM__angle", "EL__unreach")
            out.update(s3=s["EL__sine"], c3=s["EL__ac_x"], gamma=s["GM__angle"], unreach=s["EL__unreach"])
            return out

        self.dp.add_wiring(after_sqrt)
        return self.stash.put(self.dp, "gamma")

    def beta(self):
        """q3 = acos(c3) (the atan2 half) || beta = atan2(a3 s3, a2 + a3 c3)."""
        k, nearest = self.k, self.nearest
        mb = k.a3_from_u
        if mb.mant < 0:
            raise ValueError("a3_from_u: negative constant not supported")
        bt = self.chain("beta")
        operand = self.word
        if mb.pre > 0:
            bt.add("bt_pre", lambda s: dict(s, s3=rshift_round(s["s3"], mb.pre, nearest),
                                            c3=rshift_round(s["c3"], mb.pre, nearest)))
            operand = const_mul_operand(k, mb, k.one_u)
        add_products(bt, "btm", [(lambda s: s["s3"], operand, mb.mant, "bps"),
                                 (lambda s: s["c3"], operand, mb.mant, "bpc")],
                     parallel=lambda s: {"sing": s["s3"] <= k.singular_s3_u}, drop_keys=("s3", "c3"))

        def beta_round(s):
            # a2 + rshift_round(p, post) == (p + bias + (a2 << post)) >> post when post > 0.
            out = drop(s, "bps", "bpc")
            out["BT__y"] = rshift_round(s["bps"], mb.post, nearest)
            if mb.post > 0:
                bias = (1 << (mb.post - 1)) if nearest else 0
                out["BT__x"] = (s["bpc"] + (bias + (k.a2_l << mb.post))).shift_right(mb.post)
            else:
                out["BT__x"] = k.a2_l + rshift_round(s["bpc"], mb.post, nearest)
            return out

        bt.add("bt_round", beta_round)
        append_chains(self.dp, "e2", namespaced(self.acos_tail, "EL__"),
                      concat("beta", bt, atan2_chain(k, "BT__", zero=False, adders=self.adders)))

    def wrapping(self, name, keys, fn):
        """A selecting stage ``fn(state, flags)`` with the wrap compares of ``keys``."""
        compares = {}
        for key in keys:
            compares.update(wrap_compares(key, self.k))
        self.selecting(name, compares, fn)

    def joints(self, pose, base, roll, gamma):
        """q2, q3, q4 - (q3's turn) and the joint offsets of q1, q2, q3, q5."""
        k, dp, stash = self.k, self.dp, self.stash
        stash.take(dp, gamma, "gamma")
        stash.take(dp, pose, "down")
        stash.take(dp, roll, "phi")

        def shoulder(s):
            down, elbow, beta, gamma = s["down"], s["EL__angle"], s["BT__angle"], s["gamma"]
            out = drop(s, "down", "EL__angle", "BT__angle", "gamma", "sing", "unreach")
            out.update(q3=Mux(down, -elbow, elbow), q2r=Mux(down, gamma + beta, gamma - beta),
                       st=s["st"] | flag(s["sing"], S.SINGULAR_ELBOW) | flag(s["unreach"], S.UNREACHABLE))
            return out

        dp.add("shoulder", shoulder)
        stash.take(dp, base, "q1")
        stash.take(dp, roll, "q5")
        off = k.offset_a
        self.wrapping("q2_wrap", ["q2r"], lambda s, f: dict(
            drop(s, "q2r", "q1", "q5"), q2=wrapped(s, f, "q2r", k), j1=_minus(s["q1"], off[0]),
            j3=_minus(s["q3"], off[2]), j5=_minus(s["q5"], off[4])))
        self.wrapping("q4_sub", ["j1", "j3", "j5"], lambda s, f: dict(
            drop(s, "q2"), t=s["phi"] - s["q2"], j2=_minus(s["q2"], off[1]),
            **{key: wrapped(s, f, key, k) for key in ("j1", "j3", "j5")}))
        self.wrapping("q4_wrap", ["t", "j2"], lambda s, f: dict(
            drop(s, "phi"), t=wrapped(s, f, "t", k), j2=wrapped(s, f, "j2", k)))
        dp.add("q4_sub2", lambda s: dict(drop(s, "q3"), t=s["t"] - s["q3"]))

    def wrap_q4(self):
        """q4 wrapped, then its offset (j4)."""
        k, off = self.k, self.k.offset_a
        if off[3]:
            self.wrapping("q4_wrap2", ["t"], lambda s, f: dict(drop(s, "t"), q4=wrapped(s, f, "t", k)))
            self.dp.add("j4_sub", lambda s: dict(drop(s, "q4"), j4=s["q4"] - off[3]))
            self.wrapping("j4_wrap", ["j4"], lambda s, f: dict(s, j4=wrapped(s, f, "j4", k)))
        else:
            # wrap(q4 - 0) == q4: q4 is already wrapped.
            self.wrapping("q4_wrap2", ["t"], lambda s, f: dict(drop(s, "t"), j4=wrapped(s, f, "t", k)))

    def round_joints(self):
        """The joints rounded back to words, flagging a saturation (internal guard bits only)."""
        words, nearest = self.words, self.nearest
        guard = words.cfg.internal_guard_bits
        if not guard:
            return
        joints = [f"j{j}" for j in range(1, 6)]
        self.dp.add("joints_round", lambda s: dict(s, **{key: rshift_round(s[key], guard, nearest)
                                                         for key in joints}))

        def joints_saturate(s):
            out, clipped = dict(s), []
            for key in joints:
                out[key], sat = saturate(s[key], words.cfg.width)
                clipped.append(sat)
            out["st"] = s["st"] | flag(Cat(*clipped).any(), S.SATURATED)
            return out

        self.dp.add("joints_sat", joints_saturate)


def _minus(value, offset):
    return value - offset if offset else value
