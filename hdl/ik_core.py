"""The inverse kinematics of the 5R arm in hardware: :class:`IKCore`, bit-exact to ``model.ik_solve``.

The whole solver is ONE :class:`~ik5r.hdl.common.Datapath` composed from the blocks' stage builders
(:func:`~ik5r.hdl.cordic.add_atan2`, the :class:`~ik5r.hdl.cordic.Rotate` micro-rotations, the
:class:`~ik5r.hdl.acos.Acos` datapath, :func:`~ik5r.hdl.sqrt.add_isqrt`,
:func:`~ik5r.hdl.common.add_products`) and small glue stages written here. Three pieces of
machinery make that composition cheap, all local to this file (the blocks are used unchanged):

* **Namespaces.** A builder's stages are built into a scratch ``Datapath`` with its fixed key names
  (``cx``, ``cy``, ``angle`` ...) and wrapped so that they see and produce only the keys under a
  prefix (``T1__cx`` ...). Declared register shapes are copied with the prefix.
* **Parallel chains.** :func:`_append_parallel` runs several chains side by side in the same
  stages: their iterated stages (micro-rotations, square-root digits) are aligned, the
  non-iterated stages before / between / after them are padded with pass-through stages, and the
  stage functions of one cycle are composed (each chain reads only its own keys). An iterated
  stage shorter than its partners is frozen by a step guard, so both architectures work.
* **Stash.** A value needed many stages after it is computed is not carried through every
  pipeline register: :meth:`_Builder.stash` takes it out of the state and :meth:`_Builder.unstash`
  brings it back. ``pipelined``: a delay line stepping every clock, as the pipeline (a register
  chain for short distances, else a RAM ring buffer with write and read counters of its own,
  one per (from, to) stage pair);
  ``compact`` (one pose in flight): the stage register itself, which holds its value until the
  next pose reaches it.
"""

from __future__ import annotations

from amaranth.hdl import Cat, Const, Module, Mux, Signal, Value, signed, unsigned
from amaranth.lib.memory import Memory

from ik5r import status as S
from ik5r import fixedpoint
from ik5r.fxconfig import Constants

from .acos import Acos
from .common import Datapath, StreamBlock, add_products, drop, rshift_round, saturate
from .cordic import Rotate, add_atan2
from .sqrt import add_isqrt, fit

__all__ = ["IKCore", "CORE_ARCHS", "core_fields"]

from .modes import CORE_ARCHS  # noqa: E402 (the core's architectures, defined once)

#: Stash distances up to this many stages use a register chain instead of a RAM ring buffer.
_REGISTER_DELAY_MAX = 4

STATUS_BITS = 6


def _flag(cond, bit: int):
    return Mux(cond, Const(bit, STATUS_BITS), Const(0, STATUS_BITS))


# --- chain machinery -----------------------------------------------------------------------------

def _namespaced(chain: Datapath, prefix: str) -> Datapath:
    """``chain``'s stages seeing only the keys under ``prefix`` (without it); others pass through."""
    size = len(prefix)
    out = Datapath(chain.name)
    out.shapes = {prefix + key: shape for key, shape in chain.shapes.items()}

    def split(s):
        inner = {key[size:]: value for key, value in s.items() if key.startswith(prefix)}
        outer = {key: value for key, value in s.items() if not key.startswith(prefix)}
        return inner, outer

    for name, fn, count, iterated in chain.stages:
        if iterated:
            def run(s, i, fn=fn):
                inner, outer = split(s)
                outer.update({prefix + key: value for key, value in fn(inner, i).items()})
                return outer
            shared = getattr(fn, "shared", None)
            if shared is not None:
                run.shared = shared.prefixed(prefix)
        else:
            def run(s, fn=fn):
                inner, outer = split(s)
                outer.update({prefix + key: value for key, value in fn(inner).items()})
                return outer
        out.stages.append((f"{prefix.rstrip('_').lower()}_{name}", run, count, iterated))
    return out


def _concat(name: str, *chains: Datapath) -> Datapath:
    out = Datapath(name)
    for chain in chains:
        out.stages.extend(chain.stages)
        out.shapes.update(chain.shapes)
    return out


def _compose(*fns):
    def run(s):
        for fn in fns:
            s = fn(s)
        return s
    return run


def _segments(chain: Datapath):
    """[N0, (I1), N1, (I2), ...]: lists of registered stage functions between iterated stages
    ``(fn, count)``. Wiring stages are folded into a neighbouring registered stage (after the
    previous one, else before the next one, else made a registered stage of their own)."""
    items = []     # ("N", fn) | ("I", fn, count) | ("W", fn)
    for _, fn, count, iterated in chain.stages:
        items.append(("I", fn, count) if iterated else ("W", fn) if count == 0 else ("N", fn))
    folded = []
    pending = []
    for item in items:
        if item[0] == "W":
            if folded and folded[-1][0] == "N" and not pending:
                folded[-1] = ("N", _compose(folded[-1][1], item[1]))
            else:
                pending.append(item[1])
            continue
        if pending:
            if item[0] == "N":
                item = ("N", _compose(*pending, item[1]))
            else:
                folded.append(("N", _compose(*pending)))
            pending = []
        folded.append(item)
    if pending:
        folded.append(("N", _compose(*pending)))
    segments = [[]]
    for item in folded:
        if item[0] == "N":
            segments[-1].append(item[1])
        else:
            segments.append((item[1], item[2]))
            segments.append([])
    return segments


def _guarded(fn, count):
    """An iterated stage function frozen once ``i >= count``."""
    def run(s, i):
        if isinstance(i, int):
            return fn(s, i) if i < count else s
        out = fn(s, i)
        active = i < count
        return {key: value if key not in s or value is s[key] else Mux(active, value, s[key])
                for key, value in out.items()}
    return run


def _append_chains(dp: Datapath, name: str, *chains: Datapath) -> None:
    """Append ``chains`` to ``dp``: side by side (see the module docstring), or one after the
    other in a datapath that shares its functional units (the compact core: the chains' CORDIC
    steps then run on one unit)."""
    if not dp.share_units:
        _append_parallel(dp, name, *chains)
        return
    for chain in chains:
        dp.declare(**chain.shapes)
        dp.stages.extend((f"{name}_{stage}", fn, count, iterated)
                         for stage, fn, count, iterated in chain.stages)


def _append_parallel(dp: Datapath, name: str, *chains: Datapath) -> None:
    """Append ``chains`` to ``dp`` side by side (see the module docstring)."""
    segs = [_segments(chain) for chain in chains]
    for chain in chains:
        dp.declare(**chain.shapes)
    depth = max(len(seg) for seg in segs)
    # A chain with fewer iterated stages waits in front: pass-through iterated stages are
    # prepended, so its loops run beside its partners' last ones.
    segs = [[[], (lambda s, i: s, 1)] * ((depth - len(seg)) // 2) + seg for seg in segs]
    for index in range(depth):
        if index % 2 == 0:
            lists = [seg[index] for seg in segs]
            length = max(len(fns) for fns in lists)
            for t in range(length):
                fns = []
                for fns_c in lists:
                    # Pad the first segment at the front (inputs wait), the others at the end.
                    pos = t - (length - len(fns_c)) if index == 0 else t
                    if 0 <= pos < len(fns_c):
                        fns.append(fns_c[pos])
                dp.add(f"{name}_{index}_{t}", _compose(*fns))
        else:
            count = max(seg[index][1] for seg in segs)
            fns = [fn if c == count else _guarded(fn, c) for fn, c in (seg[index] for seg in segs)]

            def iterated(s, i, fns=fns):
                for fn in fns:
                    s = fn(s, i)
                return s
            dp.add_iter(f"{name}_it{index}", iterated, count)


# --- chains built from the blocks' builders -------------------------------------------------------

def _atan2_chain(k: Constants, prefix: str, *, zero: bool) -> Datapath:
    """atan2(prefix+y, prefix+x) -> prefix+angle (and prefix+zero)."""
    chain = Datapath(prefix)
    add_atan2(chain, k, y="y", x="x", magnitude=False, zero=zero)
    return _namespaced(chain, prefix)


def _rotate_const_chain(k: Constants, prefix: str, vector: tuple[int, int], *,
                        skewed: bool) -> Datapath:
    """``model.cordic_rotate(*vector, state[prefix+angle])`` of a constant vector -> prefix+x, y,
    saturated. The quadrant step and the 1/K gain of a constant vector are constants: one stage
    (compare + subtract; ``skewed``: two, the compares registered first) replaces the Rotate
    block's quadrant, coarse and multiplier stages; the micro-rotations, rounding and clipping are
    the Rotate block's own stages (``skewed``: see :meth:`Rotate._datapath`)."""
    c = k.cfg
    rot = Rotate._datapath(k, skewed=skewed)
    names = [name for name, _, _, _ in rot.stages]
    if "ro_it" not in names:
        raise RuntimeError("Rotate datapath has no 'ro_it' stage")
    tail = rot.stages[names.index("ro_it"):]
    x0, y0 = vector
    shift = k.inv_gain_frac - c.guard_bits

    def gained(x, y):
        return (fixedpoint.rshift_round(x * k.inv_gain, shift, c.round_nearest),
                fixedpoint.rshift_round(y * k.inv_gain, shift, c.round_nearest))

    cases = {"up": gained(-y0, x0), "down": gained(y0, -x0), "none": gained(x0, y0)}
    h = k.half_pi_z

    def z_of(s):
        return s["angle"].shift_left(c.angle_guard_bits)

    def quadrant(s, flags):
        z, up, down = z_of(s), flags["up"], flags["down"]
        out = drop(s, "angle")
        out["cx"] = Mux(up, cases["up"][0], Mux(down, cases["down"][0], cases["none"][0]))
        out["cy"] = Mux(up, cases["up"][1], Mux(down, cases["down"][1], cases["none"][1]))
        out["cz"] = Mux(up, z - h, Mux(down, z + h, z))
        return out

    chain = Datapath(prefix)
    chain.shapes = dict(rot.shapes)
    _add_selecting(chain, "ro_const", {"up": lambda s: z_of(s) > h, "down": lambda s: z_of(s) < -h},
                   quadrant, registered=skewed)
    chain.stages.extend(tail)
    return _namespaced(chain, prefix)


def _const_mul_operand(k: Constants, m, bound: int):
    """Shape of rshift_round(x, m.pre) for |x| <= bound."""
    nearest = k.cfg.round_nearest
    top = max(abs(fixedpoint.rshift_round(bound, m.pre, nearest)),
              abs(fixedpoint.rshift_round(-bound, m.pre, nearest)))
    return signed(top.bit_length() + 1)


# --- the stash -----------------------------------------------------------------------------------

class _Builder:
    """Holds the per-elaboration stash registry of an IKCore's datapath."""

    def __init__(self):
        self.reset()

    def reset(self):
        self.stashed = {}
        self.links = []

    def stash(self, dp: Datapath, *keys):
        where = dp.latency

        def fn(s):
            for key in keys:
                self.stashed[key] = (s[key], where)
            return drop(s, *keys)
        dp.add_wiring(fn)

    def unstash(self, dp: Datapath, *keys):
        where = dp.latency

        def fn(s):
            out = dict(s)
            for key in keys:
                value, origin = self.stashed.pop(key)
                value = Value.cast(value)
                if where - origin < 1:
                    raise ValueError(f"stash of {key!r}: zero distance")
                dst = Signal(value.shape(), name=f"stash_{key}")
                self.links.append((key, value, origin, where, dst))
                out[key] = dst
            return out
        dp.add_wiring(fn)

    def elaborate(self, m: Module, arch: str):
        """Drive the unstashed signals (after ``Datapath.build``)."""
        if self.stashed:
            raise ValueError(f"stashed but never used: {sorted(self.stashed)}")
        if arch != "pipelined":
            # One item in flight: the source register holds its value until the next item.
            for _, value, _, _, dst in self.links:
                m.d.comb += dst.eq(value)
            return
        groups = {}
        for link in self.links:
            groups.setdefault((link[2], link[3]), []).append(link)
        for (origin, where), links in sorted(groups.items()):
            distance = where - origin
            word = Cat(*(link[1] for link in links))
            if distance <= _REGISTER_DELAY_MAX:
                for step in range(distance):
                    reg = Signal(len(word), name=f"stash_{origin}_{where}_d{step}", reset_less=True)
                    m.d.sync += reg.eq(word)
                    word = reg
                out = word
            else:
                depth = 1 << (distance - 1).bit_length()
                bits = (depth - 1).bit_length()
                mem = Memory(shape=unsigned(len(word)), depth=depth, init=[])
                m.submodules[f"stash_{origin}_{where}"] = mem
                wp = mem.write_port()
                rp = mem.read_port(transparent_for=())
                # Write and read addresses are counters of their own next to each RAM, stepped
                # every clock (the read one distance - 2 behind, then a register): one address
                # counter shared by all the RAMs, and a subtractor per RAM, made the slowest path.
                write_ptr = Signal(unsigned(bits), name=f"stash_{origin}_{where}_wptr")
                read_ptr = Signal(unsigned(bits), name=f"stash_{origin}_{where}_rptr",
                                  init=-(distance - 2) % depth)
                m.d.sync += [write_ptr.eq(write_ptr + 1), read_ptr.eq(read_ptr + 1)]
                m.d.comb += [
                    wp.addr.eq(write_ptr), wp.data.eq(word), wp.en.eq(1),
                    rp.addr.eq(read_ptr),
                ]
                # The read data is registered before its user (an adder, often): an ECP5 block
                # RAM's clock-to-output without its output register is over 4 ns, near half of
                # a 100 MHz cycle.
                out = Signal(len(word), name=f"stash_{origin}_{where}_q", reset_less=True)
                m.d.sync += out.eq(rp.data)
            lsb = 0
            for _, value, _, _, dst in links:
                part = out[lsb:lsb + len(value)]
                m.d.comb += dst.eq(part.as_signed() if value.shape().signed else part)
                lsb += len(value)


# --- the core ------------------------------------------------------------------------------------

def _add_selecting(dp: Datapath, name: str, compares: dict, fn, *, registered: bool) -> None:
    """Stage ``name``: ``fn(state, flags)`` with ``flags[key] = compares[key](state)``, the
    compares that select its values.

    ``registered`` (the pipelined core): the compares run one stage earlier, in ``name_cmp``, and
    reach ``fn`` from registers. On ECP5 a compare's carry chain followed by a select as wide as
    the word took 10.1 ns (the q32w core's critical path at 98.9 MHz); split, each stage is one
    carry chain or one select behind a register.
    """
    if not registered:
        dp.add(name, lambda s: fn(s, {key: compare(s) for key, compare in compares.items()}))
        return
    keys = {key: f"{name}_{key}" for key in compares}
    dp.add(f"{name}_cmp", lambda s: dict(s, **{keys[key]: compare(s)
                                               for key, compare in compares.items()}))
    dp.add(name, lambda s: fn(drop(s, *keys.values()), {key: s[keys[key]] for key in keys}))


def _wrap_compares(key: str, k: Constants) -> dict:
    """The compares of ``model.wrap_angle`` of ``state[key]`` (flags ``key_over``, ``key_under``)."""
    return {f"{key}_over": lambda s: s[key] > k.pi_a, f"{key}_under": lambda s: s[key] < -k.pi_a}


def _wrapped(s, flags, key: str, k: Constants):
    """``model.wrap_angle`` of ``s[key]``: one correction by a turn, as its compares select."""
    value, turn = s[key], 2 * k.pi_a
    return Mux(flags[f"{key}_over"], value - turn, Mux(flags[f"{key}_under"], value + turn, value))


def _opposite(angle, positive, k: Constants):
    """``model.opposite`` of ``angle``, ``positive`` being ``angle > 0``."""
    return Mux(positive, angle - k.pi_a, angle + k.pi_a)


def _add_c3(el: Datapath, k: Constants, limit: int, *, registered: bool) -> None:
    """c3 = clip(mul_const(num, c3_from_l2)) -> ``ac_x`` (the Acos datapath's clipped input)."""
    nearest, one = k.cfg.round_nearest, k.one_u
    mc = k.c3_from_l2
    if mc.mant < 0:
        raise ValueError("c3_from_l2: negative constant not supported")
    el.add("c3_pre", lambda s: dict(drop(s, "numc"), c3v=rshift_round(s["numc"], mc.pre, nearest)))
    add_products(el, "c3m", [(lambda s: s["c3v"], _const_mul_operand(k, mc, limit), mc.mant, "c3p")],
                 drop_keys=("c3v",))
    el.add("c3_post", lambda s: dict(drop(s, "c3p"), c3r=rshift_round(s["c3p"], mc.post, nearest)))
    _add_selecting(el, "c3_clip", {"over": lambda s: s["c3r"] > one, "under": lambda s: s["c3r"] < -one},
                   lambda s, f: dict(drop(s, "c3r"), ac_x=Mux(f["over"], one,
                                                              Mux(f["under"], -one, s["c3r"]))),
                   registered=registered)


def _add_c3_complements(el: Datapath, k: Constants, limit: int, *, registered: bool) -> None:
    """1 - c3 and 1 + c3 straight from the law of cosines (the internal format's way, see
    ``model.ik_solve``): mul_const(2 a2 a3 -+ num, c3_complement_from_l2), each clipped to 2 ->
    ``ac_a``, ``ac_b`` (the Acos datapath's factors) and c3 = 1 - (1 - c3) -> ``ac_x``."""
    nearest, one, fu = k.cfg.round_nearest, k.one_u, k.cfg.frac_unit
    two = 2 * one
    mc = k.c3_complement_from_l2
    if mc.mant < 0:
        raise ValueError("c3_complement_from_l2: negative constant not supported")
    el.add("c3_pre", lambda s: dict(drop(s, "numc"),
                                    cmv=rshift_round(limit - s["numc"], mc.pre, nearest),
                                    cpv=rshift_round(limit + s["numc"], mc.pre, nearest)))
    operand = _const_mul_operand(k, mc, 2 * limit)
    add_products(el, "c3m", [(lambda s: s["cmv"], operand, mc.mant, "cmp"),
                             (lambda s: s["cpv"], operand, mc.mant, "cpp")], drop_keys=("cmv", "cpv"))
    el.add("c3_post", lambda s: dict(drop(s, "cmp", "cpp"),
                                     cmr=rshift_round(s["cmp"], mc.post, nearest),
                                     cpr=rshift_round(s["cpp"], mc.post, nearest)))

    def clip(s, flags):
        over = flags["minus_over"]
        minus, plus = Mux(over, two, s["cmr"]), Mux(flags["plus_over"], two, s["cpr"])
        return dict(drop(s, "cmr", "cpr"), ac_a=minus[:fu + 2], ac_b=plus[:fu + 2],
                    ac_x=Mux(over, one - two, one - s["cmr"]))

    _add_selecting(el, "c3_clip", {"minus_over": lambda s: s["cmr"] > two,
                                   "plus_over": lambda s: s["cpr"] > two},
                   clip, registered=registered)


# --- orientation checks (model.frame_is_bad, model.off_plane) -----------------------------------
# Products of check words (the top 17 bits of a unit word: one 17 x 17 partial product each), computed
# beside the dot products: 15 for the n, o, a frame (n.n, o.o, n.o, n x o), 2 for the approach's
# component normal to the arm's plane (ay c1 - ax s1). Keys ``ck*``.

_FRAME_PAIRS = (("nx", "nx"), ("ny", "ny"), ("nz", "nz"), ("ox", "ox"), ("oy", "oy"), ("oz", "oz"),
                ("nx", "ox"), ("ny", "oy"), ("nz", "oz"), ("ny", "oz"), ("nz", "oy"), ("nz", "ox"),
                ("nx", "oz"), ("nx", "oy"), ("ny", "ox"))


def _orientation_specs(words: Constants) -> list:
    """add_products specs of the checks' 17 products (``ck0`` .. ``ck16``)."""
    ki = words.internal
    frame_shift = words.cfg.internal_guard_bits + words.check_shift   # internal word -> its word's check word
    plane_shift = ki.check_shift
    frame = signed(ki.cfg.width - frame_shift)
    plane = signed(ki.cfg.width - plane_shift)

    def of(key, shift):
        return lambda s: s[key].shift_right(shift)

    specs = [(of(x, frame_shift), frame, (of(y, frame_shift), frame), f"ck{i}")
             for i, (x, y) in enumerate(_FRAME_PAIRS)]
    specs += [(of("ay", plane_shift), plane, (of("C1__x", plane_shift), plane), "ck15"),
              (of("ax", plane_shift), plane, (of("C1__y", plane_shift), plane), "ck16")]
    return specs


def _orientation_operands(s, words: Constants) -> dict:
    """The approach's check words (n x o is compared with them), kept beside the products."""
    shift = words.cfg.internal_guard_bits + words.check_shift
    return {f"cka{axis}": s[f"a{axis}"].shift_right(shift) for axis in "xyz"}


def _orientation_sums(s) -> dict:
    """First adder level: two-term sums and the cross product's differences."""
    out = drop(s, *(f"ck{i}" for i in (0, 1, 3, 4, 6, 7, 9, 10, 11, 12, 13, 14, 15, 16)))
    out.update(ckn=s["ck0"] + s["ck1"], cko=s["ck3"] + s["ck4"], ckno=s["ck6"] + s["ck7"],
               ckcx=s["ck9"] - s["ck10"], ckcy=s["ck11"] - s["ck12"], ckcz=s["ck13"] - s["ck14"],
               ckpl=s["ck15"] - s["ck16"])
    return out


def _orientation_terms(s, words: Constants) -> dict:
    """Second adder level: the third terms of the dot products, n x o - a."""
    frac = words.check_frac
    out = drop(s, "ck2", "ck5", "ck8", "ckax", "ckay", "ckaz")
    out.update(ckn=s["ckn"] + s["ck2"], cko=s["cko"] + s["ck5"], ckno=s["ckno"] + s["ck8"],
               **{f"ckc{axis}": s[f"ckc{axis}"] - s[f"cka{axis}"].shift_left(frac) for axis in "xyz"})
    return out


def _orientation_flag(s, words: Constants):
    """(state without the check keys, BAD_ORIENTATION status bits): off the plane, or (with roll)
    a frame error beyond the tolerance."""
    ki = words.internal

    def beyond(value, centre, k):
        return (value > centre + k.check_tol_c2) | (value < centre - k.check_tol_c2)

    frame = (beyond(s["ckn"], words.check_one_c2, words) | beyond(s["cko"], words.check_one_c2, words)
             | beyond(s["ckno"], 0, words)
             | beyond(s["ckcx"], 0, words) | beyond(s["ckcy"], 0, words) | beyond(s["ckcz"], 0, words))
    bad = beyond(s["ckpl"], 0, ki) | (s["roll"] & frame)
    return drop(s, "ckn", "cko", "ckno", "ckcx", "ckcy", "ckcz", "ckpl"), _flag(bad, S.BAD_ORIENTATION)


def _core_datapath(words: Constants, builder: _Builder, tag: bool, compact: bool) -> Datapath:
    """The IK on the internal format ``k = words.internal`` (the words themselves unless the config
    has ``ik.internal_guard_bits``); the inputs arrive shifted up (:meth:`IKCore._inputs`) and the
    joints leave rounded back to words."""
    k = words.internal
    c = k.cfg
    width, fu, nearest = c.width, c.frac_unit, c.round_nearest
    word = signed(width)
    products = "sequential" if compact else "parallel"
    dp = Datapath("ik", products=products, share_units=compact)

    # ---- Stage 0: joint-1 vector (the point, or the approach on the base axis); d1 - pz.
    def select(s):
        px, py = s["px"], s["py"]
        on_axis = (px == 0) & (py == 0)
        out = drop(s, "px", "py", "pz")
        out.update({"T1__y": Mux(on_axis, s["ay"], py), "T1__x": Mux(on_axis, s["ax"], px),
                    "RH__px": px, "RH__py": py, "dz": k.d1_l - s["pz"]})
        return out

    dp.add("select", select)
    builder.stash(dp, "dz", "ax", "ay", "az", "nx", "ny", "nz", "ox", "oy", "oz", "roll", "q5d", "back", "down",
                  *(("tag",) if tag else ()))

    # ---- theta1 = atan2(py, px) || rho = sat(isqrt(px^2 + py^2)) (2W-bit radicand: the model's
    # 64-bit one has only zero bit pairs above px^2 + py^2 < 2**(2W-1)).
    rho = Datapath("rho", products=products)
    add_products(rho, "sq", [(lambda s: s["px"], word, (lambda s: s["px"], word), "xx"),
                             (lambda s: s["py"], word, (lambda s: s["py"], word), "yy")],
                 drop_keys=("px", "py"))
    rho.add("sum", lambda s: dict(drop(s, "xx", "yy"), sq_rad=fit(s["xx"] + s["yy"], 2 * width)))
    add_isqrt(rho, bits=2 * width, nearest=nearest, root="root")

    def rho_sat(s):
        value, sat = saturate(s["root"], width)
        return dict(drop(s, "root"), rho=value, sat=sat)

    rho.add("sat", rho_sat)
    _append_chains(dp, "p1", _atan2_chain(k, "T1__", zero=True), _namespaced(rho, "RH__"))

    # ---- q1 (branch), r - a1; then (c1, s1) = rotate((1, 0), q1).
    builder.unstash(dp, "back")

    def joint1(s, flags):
        theta, back, rho_l = s["T1__angle"], s["back"], s["RH__rho"]
        q1 = Mux(back, _opposite(theta, flags["positive"], k), theta)
        out = drop(s, "T1__angle", "T1__zero", "RH__rho", "RH__sat", "back")
        out.update(q1=q1, C1__angle=q1, xa=Mux(back, -k.a1_l - rho_l, rho_l - k.a1_l),
                   st=_flag(s["T1__zero"], S.SINGULAR_BASE) | _flag(s["RH__sat"], S.SATURATED))
        return out

    _add_selecting(dp, "joint1", {"positive": lambda s: s["T1__angle"] > 0}, joint1,
                   registered=not compact)
    builder.stash(dp, "q1", "xa")
    _append_chains(dp, "c1", _rotate_const_chain(k, "C1__", (k.one_u, 0), skewed=not compact))

    # ---- a_radial = a . (c1, s1); s5, c5 = n, o . (s1, -c1): six products, sums, rounding.
    builder.unstash(dp, "ax", "ay", "az", "nx", "ny", "nz", "ox", "oy", "oz", "roll")
    c1_of, s1_of = (lambda s: s["C1__x"]), (lambda s: s["C1__y"])
    add_products(dp, "dot", _orientation_specs(words) + [
        (lambda s: s["ax"], word, (c1_of, word), "pa1"), (lambda s: s["ay"], word, (s1_of, word), "pa2"),
        (lambda s: s["nx"], word, (s1_of, word), "pn1"), (lambda s: s["ny"], word, (c1_of, word), "pn2"),
        (lambda s: s["ox"], word, (s1_of, word), "po1"), (lambda s: s["oy"], word, (c1_of, word), "po2"),
    ], parallel=lambda s: {"st": s["st"] | _flag(s["C1__saturated"], S.SATURATED),
                           **_orientation_operands(s, words)},
        drop_keys=("ax", "ay", "nx", "ny", "nz", "ox", "oy", "oz", "C1__x", "C1__y", "C1__saturated"))
    dp.add("dot_sum", lambda s: dict(drop(_orientation_sums(s), "pa1", "pa2", "pn1", "pn2", "po1", "po2"),
                                     da=s["pa1"] + s["pa2"], dn=s["pn1"] - s["pn2"],
                                     do=s["po1"] - s["po2"]))
    dp.add("dot_round", lambda s: dict(_orientation_terms(s, words),
                                       **{key: rshift_round(s[key], fu, nearest) for key in ("da", "dn", "do")}))

    def dot_saturate(s):
        a_rad, sat_a = saturate(s["da"], width)
        s5, sat_s = saturate(s["dn"], width)
        c5, sat_c = saturate(s["do"], width)
        s, orientation = _orientation_flag(s, words)
        out = drop(s, "da", "dn", "do", "az")
        out.update({"PT__y": a_rad, "PT__x": s["az"], "Q5__y": s5, "Q5__x": c5,
                    "st": s["st"] | orientation | _flag(sat_a | ((sat_s | sat_c) & s["roll"]), S.SATURATED)})
        return out

    dp.add("dot_sat", dot_saturate)

    # ---- pitch = atan2(a_radial, az) || roll = atan2(s5, c5).
    _append_chains(dp, "p3", _atan2_chain(k, "PT__", zero=True), _atan2_chain(k, "Q5__", zero=True))
    builder.unstash(dp, "q5d")

    def pitch(s, flags):
        phi = _opposite(s["PT__angle"], flags["positive"], k)
        roll = s["roll"]
        out = drop(s, "PT__angle", "PT__zero", "Q5__angle", "Q5__zero", "roll", "q5d")
        out.update(phi=phi, R2__angle=phi, q5=Mux(roll, s["Q5__angle"], s["q5d"]),
                   st=s["st"] | _flag(s["PT__zero"] | (roll & s["Q5__zero"]), S.INVALID))
        return out

    _add_selecting(dp, "pitch", {"positive": lambda s: s["PT__angle"] > 0}, pitch,
                   registered=not compact)
    builder.stash(dp, "phi", "q5")

    # ---- wrist centre: (xw, yw) = sat((r - a1, d1 - pz) - R(phi) (a4, d5)).
    _append_chains(dp, "r2", _rotate_const_chain(k, "R2__", (k.a4_l, k.d5_l), skewed=not compact))
    builder.unstash(dp, "xa", "dz")
    dp.add("wrist", lambda s: dict(drop(s, "xa", "dz", "R2__x", "R2__y", "R2__saturated"),
                                   xwr=s["xa"] - s["R2__x"], ywr=s["dz"] - s["R2__y"],
                                   st=s["st"] | _flag(s["R2__saturated"], S.SATURATED)))

    def wrist_saturate(s):
        xw, sat_x = saturate(s["xwr"], width)
        yw, sat_y = saturate(s["ywr"], width)
        out = drop(s, "xwr", "ywr")
        out.update({"GM__y": yw, "GM__x": xw, "EL__xw": xw, "EL__yw": yw,
                    "st": s["st"] | _flag(sat_x | sat_y, S.SATURATED)})
        return out

    dp.add("wrist_sat", wrist_saturate)

    # ---- gamma = atan2(yw, xw) || c3 = clip(mul_const(clip(xw^2 + yw^2 - links), c3_from_l2))
    # and the first half of acos (sine by the square root).
    el = Datapath("elbow", products=products)
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

    _add_selecting(el, "reach", {"over": lambda s: s["num"] > limit, "under": lambda s: s["num"] < -limit,
                                 "far_over": lambda s: s["num"] > reach_limit,
                                 "far_under": lambda s: s["num"] < -reach_limit},
                   reach, registered=not compact)
    one = k.one_u
    if words.cfg.internal_guard_bits == 0:
        _add_c3(el, k, limit, registered=not compact)
        acos = Acos._datapath(k, products)
        first_acos = [name for name, _, _, _ in acos.stages].index("ac_factors")
    else:
        _add_c3_complements(el, k, limit, registered=not compact)
        acos = Acos._datapath(k, products, radicand_bits=2 * fu + 4)
        first_acos = [name for name, _, _, _ in acos.stages].index("ac_sq_op")
    names = [name for name, _, _, _ in acos.stages]
    first_atan = next(i for i, name in enumerate(names) if name.startswith("at_"))
    el.shapes.update(acos.shapes)
    el.stages.extend(acos.stages[first_acos:first_atan])
    acos_tail = Datapath("acos_tail")
    acos_tail.shapes = dict(acos.shapes)
    acos_tail.stages = list(acos.stages[first_atan:])
    _append_chains(dp, "e1", _atan2_chain(k, "GM__", zero=False), _namespaced(el, "EL__"))

    def after_sqrt(s):
        out = drop(s, "EL__sine", "GM__angle", "EL__unreach")
        out.update(s3=s["EL__sine"], c3=s["EL__ac_x"], gamma=s["GM__angle"], unreach=s["EL__unreach"])
        return out

    dp.add_wiring(after_sqrt)
    builder.stash(dp, "gamma")

    # ---- q3 = acos(c3) (the atan2 half) || beta = atan2(a3 s3, a2 + a3 c3).
    mb = k.a3_from_u
    if mb.mant < 0:
        raise ValueError("a3_from_u: negative constant not supported")
    bt = Datapath("beta", products=products)
    operand = word
    if mb.pre > 0:
        bt.add("bt_pre", lambda s: dict(s, s3=rshift_round(s["s3"], mb.pre, nearest),
                                        c3=rshift_round(s["c3"], mb.pre, nearest)))
        operand = _const_mul_operand(k, mb, k.one_u)
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
    _append_chains(dp, "e2", _namespaced(acos_tail, "EL__"),
                     _concat("beta", bt, _atan2_chain(k, "BT__", zero=False)))

    # ---- q2, q3, q4 and the joint offsets.
    builder.unstash(dp, "gamma", "down", "phi")

    def shoulder(s):
        down, elbow, beta, gamma = s["down"], s["EL__angle"], s["BT__angle"], s["gamma"]
        out = drop(s, "down", "EL__angle", "BT__angle", "gamma", "sing", "unreach")
        out.update(q3=Mux(down, -elbow, elbow), q2r=Mux(down, gamma + beta, gamma - beta),
                   st=s["st"] | _flag(s["sing"], S.SINGULAR_ELBOW) | _flag(s["unreach"], S.UNREACHABLE))
        return out

    dp.add("shoulder", shoulder)
    builder.unstash(dp, "q1", "q5")
    off = k.offset_a

    def minus(value, offset):
        return value - offset if offset else value

    def wrapping(name, keys, fn):
        compares = {}
        for key in keys:
            compares.update(_wrap_compares(key, k))
        _add_selecting(dp, name, compares, fn, registered=not compact)

    wrapping("q2_wrap", ["q2r"], lambda s, f: dict(drop(s, "q2r", "q1", "q5"), q2=_wrapped(s, f, "q2r", k),
                                                   j1=minus(s["q1"], off[0]), j3=minus(s["q3"], off[2]),
                                                   j5=minus(s["q5"], off[4])))
    wrapping("q4_sub", ["j1", "j3", "j5"],
             lambda s, f: dict(drop(s, "q2"), t=s["phi"] - s["q2"], j2=minus(s["q2"], off[1]),
                               **{key: _wrapped(s, f, key, k) for key in ("j1", "j3", "j5")}))
    wrapping("q4_wrap", ["t", "j2"], lambda s, f: dict(drop(s, "phi"), t=_wrapped(s, f, "t", k),
                                                       j2=_wrapped(s, f, "j2", k)))
    dp.add("q4_sub2", lambda s: dict(drop(s, "q3"), t=s["t"] - s["q3"]))
    if tag:
        builder.unstash(dp, "tag")
    if off[3]:
        wrapping("q4_wrap2", ["t"], lambda s, f: dict(drop(s, "t"), q4=_wrapped(s, f, "t", k)))
        dp.add("j4_sub", lambda s: dict(drop(s, "q4"), j4=s["q4"] - off[3]))
        wrapping("j4_wrap", ["j4"], lambda s, f: dict(s, j4=_wrapped(s, f, "j4", k)))
    else:
        # wrap(q4 - 0) == q4: q4 is already wrapped.
        wrapping("q4_wrap2", ["t"], lambda s, f: dict(drop(s, "t"), j4=_wrapped(s, f, "t", k)))
    guard = words.cfg.internal_guard_bits
    if guard:
        joints = [f"j{j}" for j in range(1, 6)]
        dp.add("joints_round", lambda s: dict(s, **{key: rshift_round(s[key], guard, nearest)
                                                    for key in joints}))

        def joints_saturate(s):
            out, clipped = dict(s), []
            for key in joints:
                out[key], sat = saturate(s[key], words.cfg.width)
                clipped.append(sat)
            out["st"] = s["st"] | _flag(Cat(*clipped).any(), S.SATURATED)
            return out

        dp.add("joints_sat", joints_saturate)
    return dp


def core_fields(constants: Constants) -> tuple[dict, dict]:
    """The IK core's payload fields (name -> (shape, fraction bits, description)), in and out."""
    c = constants.cfg
    word = signed(c.width)
    bit = unsigned(1)
    fl, fu, fa = c.frac_length, c.frac_unit, c.frac_angle
    in_fields = {
        "px": (word, fl, "tool point x, cm"), "py": (word, fl, "tool point y, cm"),
        "pz": (word, fl, "tool point z, cm"),
        "ax": (word, fu, "approach x"), "ay": (word, fu, "approach y"),
        "az": (word, fu, "approach z"),
        "nx": (word, fu, "normal x (read if has_roll)"), "ny": (word, fu, "normal y"),
        "nz": (word, fu, "normal z (orientation check)"),
        "ox": (word, fu, "orientation x (read if has_roll)"), "oy": (word, fu, "orientation y"),
        "oz": (word, fu, "orientation z (orientation check)"),
        "has_roll": (bit, 0, "q5 from n, o (else q5_default)"),
        "q5_default": (word, fa, "q5 without roll, rad"),
        "shoulder_back": (bit, 0, "branch: tool point behind joint 1 (q1 + pi)"),
        "elbow_down": (bit, 0, "branch: q3 = -acos(c3)"),
    }
    out_fields = {f"q{j}": (word, fa, f"joint {j} angle, rad, in [-pi, pi]")
                  for j in range(1, 6)}
    out_fields["status"] = (unsigned(STATUS_BITS), 0, "ik5r.status bits")
    return in_fields, out_fields


class IKCore(StreamBlock):
    """The fixed-point inverse kinematics of the 5R arm, bit-exact to ``model.ik_solve``.

    One pose in, one branch's joint angles and status out. The branch is chosen per pose, as in
    the C solver's API (``ik5r_solve(..., has_roll, shoulder_back, elbow_down, q5_default_a, q)``):
    ``shoulder_back`` puts the tool point behind joint 1 (q1 + pi, r = -rho), ``elbow_down`` takes
    q3 = -acos(c3) (q2 = gamma + beta) instead of +acos(c3) (q2 = gamma - beta). Without roll
    (``has_roll`` low) n and o are ignored and q5 = ``q5_default`` (wrapped).

    Dataflow (docs/algorithm.md; every step is the model's, in the model's integer arithmetic):
    select (point, or approach on the base axis) -> [atan2 theta1 || px^2 + py^2, isqrt, sat rho]
    -> q1, r - a1 -> rotate (1, 0) by q1 -> six products: a_radial, s5, c5 -> [atan2 pitch ||
    atan2 roll] -> phi -> rotate (a4, d5) by phi -> wrist centre (xw, yw) -> [atan2 gamma ||
    xw^2 + yw^2 - links, clip, c3 = mul_const, clip, (1 - c3)(1 + c3), isqrt = sin q3] ->
    [atan2(sin q3, c3) = acos || a3 sin q3, a2 + a3 c3, atan2 beta] -> q2, q3, q4 -> offsets, wrap.
    Parallel CORDICs share stages; values needed much later are stashed in delay lines.

    With ``ik.internal_guard_bits`` = G > 0 (q32w: G = 6) every step runs on the internal format
    (W + G-bit words, every fraction + G, iterations + G; 1 -+ c3 as two constant multiplies of
    the law of cosines' terms instead of c3 and 1 -+ c3); the input words are shifted up on entry and
    the joints rounded back to words (flagging ``saturated`` if one overflows).

    Payloads (W = ``constants.cfg.width``; Q m.n: n fraction bits, m + n = W):

    * ``i.payload``: ``px``, ``py``, ``pz`` ``signed(W)`` Q.frac_length cm; ``ax``, ``ay``, ``az``,
      ``nx``, ``ny``, ``nz``, ``ox``, ``oy``, ``oz`` ``signed(W)`` Q.frac_unit (nz, oz only in the
      orientation check); ``has_roll``, ``shoulder_back``, ``elbow_down`` 1 bit; ``q5_default``
      ``signed(W)`` Q.frac_angle rad; ``tag`` ``unsigned(tag_width)`` (only if ``tag_width``).
      Every word is accepted (full-scale and most negative inputs give the model's result).
    * ``o.payload``: ``q1`` .. ``q5`` ``signed(W)`` Q.frac_angle rad in [-pi, pi] (q5: the wrapped
      default without roll); ``status`` ``unsigned(6)``, the bits of :mod:`ik5r.status`
      (unreachable, singular_elbow, singular_base, saturated, invalid, bad_orientation); ``tag``,
      the input's.

    Timing: ``latency`` cycles from the input transfer to the output valid (no back-pressure),
    see ``latency`` (pipelined: q32w 323, q32 274, q18 190, of which 3 in the output FIFO and the
    register in front of it; compact: q32w 502, q32 411, q18 271 cycles).

    * ``"pipelined"``: one pose per clock (``cycles_per_result`` = 1), results in order. The
      pipeline never stalls (no clock enable): results queue in an output FIFO (block RAM) while
      ``o`` is held, and ``i.ready`` drops only when ``capacity`` poses (q32 513, q18 257) are
      inside, in flight or queued (see :class:`~ik5r.hdl.common.StreamBlock`). One add/sub level
      (or one 17 x 17 partial product) per stage; a compare that selects a value is registered
      a stage ahead of its select. ``dsp="ecp5"`` builds the partial products as
      ``MULT18X18D`` instances with their input and output registers and the CORDIC
      add/subtracts as ``CCU2C`` chains (same latency, same bits).
    * ``"compact"``: the same steps, sequenced, for small FPGAs: one pose in flight
      (``cycles_per_result`` = ``latency``; a new pose is accepted when idle or in the cycle the
      previous result leaves). All eight CORDICs (six vectoring, two rotation) run one after the
      other on ONE shared micro-rotation unit (:func:`~ik5r.hdl.cordic.cordic_unit`, one step per
      clock); each of the 14 multipliers is one 18 x 18 DSP stepped over its partial products
      (``products="sequential"``); the two square roots are digit-serial. The other steps (glue,
      rounding, saturation) keep their own registers, each used for one clock per pose.
      ``hdl.generate`` names this elaboration ``staged``: its ``compact`` IK core is the much
      smaller sequenced engine, :class:`~ik5r.hdl.seq_core.SequencedIKCore`.
    """

    def __init__(self, *, constants: Constants, arch: str, tag_width: int = 0,
                 dsp: str = "generic"):
        if arch not in CORE_ARCHS:
            raise ValueError(f"arch must be one of {CORE_ARCHS}, got {arch!r}")
        dp = in_fields = out_fields = None
        self._builder = _Builder()
        if isinstance(constants, Constants):
            in_fields, out_fields = core_fields(constants)
            dp = _core_datapath(constants, self._builder, bool(tag_width), arch == "compact")
        self.options = {}
        super().__init__(constants=constants, arch="pipelined" if arch == "pipelined" else "iterative",
                         tag_width=tag_width, in_fields=in_fields, out_fields=out_fields, datapath=dp,
                         dsp=dsp)
        self.arch = arch
        self.cycles_per_result = 1 if arch == "pipelined" else dp.latency

    def _inputs(self, p):
        # Words to the internal format: exact, ``internal_guard_bits`` more fraction bits.
        guard = self.constants.cfg.internal_guard_bits
        def word(value):
            return value.shift_left(guard)

        return {"px": word(p.px), "py": word(p.py), "pz": word(p.pz), "ax": word(p.ax),
                "ay": word(p.ay), "az": word(p.az), "nx": word(p.nx), "ny": word(p.ny),
                "nz": word(p.nz), "ox": word(p.ox), "oy": word(p.oy), "oz": word(p.oz), "roll": p.has_roll, "q5d": word(p.q5_default),
                "back": p.shoulder_back, "down": p.elbow_down}

    def _outputs(self, state):
        out = {f"q{j}": state[f"j{j}"] for j in range(1, 6)}
        out["status"] = state["st"]
        return out

    def elaborate(self, platform):
        self._builder.reset()
        m = super().elaborate(platform)
        self._builder.elaborate(m, self._datapath_arch)
        return m
