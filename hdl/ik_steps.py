"""Steps of the IK core's datapath (:mod:`.ik_datapath`): the blocks' chains it runs under a
namespace (atan2, the rotation of a constant vector), the angle wrap and opposite, and the
law-of-cosines constant multiplies into the arc cosine's input; the status flags."""

from __future__ import annotations

from amaranth.hdl import Const, Mux, signed

from ik5r.core import fixedpoint
from ik5r.core.fxconfig import Constants

from .chains import add_selecting, namespaced
from .cordic import Rotate, add_atan2
from .datapath import Datapath
from .expr import drop, rshift_round
from .products import add_products

__all__ = ["STATUS_BITS", "flag", "atan2_chain", "rotate_const_chain", "const_mul_operand",
           "wrap_compares", "wrapped", "opposite", "add_c3", "add_c3_complements"]

STATUS_BITS = 6


def flag(cond, bit: int):
    """``bit`` of the status word when ``cond``, else 0."""
    return Mux(cond, Const(bit, STATUS_BITS), Const(0, STATUS_BITS))


def atan2_chain(k: Constants, prefix: str, *, zero: bool, adders) -> Datapath:
    """atan2(prefix+y, prefix+x) -> prefix+angle (and prefix+zero)."""
    chain = Datapath(prefix, adders=adders, inputs=("y", "x"),
                     outputs=("angle", "zero") if zero else ("angle",))
    add_atan2(chain, k, y="y", x="x", magnitude=False, zero=zero)
    return namespaced(chain, prefix)


def rotate_const_chain(k: Constants, prefix: str, vector: tuple[int, int], *,
                        skewed: bool, adders) -> Datapath:
    """``model.cordic_rotate(*vector, state[prefix+angle])`` of a constant vector -> prefix+x, y,
    saturated. The quadrant step and the 1/K gain of a constant vector are constants: one stage
    (compare + subtract; ``skewed``: two, the compares registered first) replaces the Rotate
    block's quadrant, coarse and multiplier stages; the micro-rotations, rounding and clipping are
    the Rotate block's own stages (``skewed``: see :meth:`Rotate.chain`)."""
    c = k.cfg
    rot = Rotate.chain(k, skewed=skewed, adders=adders)
    tail = rot.part("micro_rotations")
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

    chain = Datapath(prefix, adders=adders, inputs=("angle",), outputs=("x", "y", "saturated"))
    chain.shapes = dict(rot.shapes)
    add_selecting(chain, "ro_const", {"up": lambda s: z_of(s) > h, "down": lambda s: z_of(s) < -h},
                   quadrant, registered=skewed)
    chain.stages.extend(tail.stages)
    return namespaced(chain, prefix)


def const_mul_operand(k: Constants, m, bound: int):
    """Shape of rshift_round(x, m.pre) for |x| <= bound."""
    nearest = k.cfg.round_nearest
    top = max(abs(fixedpoint.rshift_round(bound, m.pre, nearest)),
              abs(fixedpoint.rshift_round(-bound, m.pre, nearest)))
    return signed(top.bit_length() + 1)


def wrap_compares(key: str, k: Constants) -> dict:
    """The compares of ``model.wrap_angle`` of ``state[key]`` (flags ``key_over``, ``key_under``)."""
    return {f"{key}_over": lambda s: s[key] > k.pi_a, f"{key}_under": lambda s: s[key] < -k.pi_a}


def wrapped(s, flags, key: str, k: Constants):
    """``model.wrap_angle`` of ``s[key]``: one correction by a turn, as its compares select."""
    value, turn = s[key], 2 * k.pi_a
    return Mux(flags[f"{key}_over"], value - turn, Mux(flags[f"{key}_under"], value + turn, value))


def opposite(angle, positive, k: Constants):
    """``model.opposite`` of ``angle``, ``positive`` being ``angle > 0``."""
    return Mux(positive, angle - k.pi_a, angle + k.pi_a)


def add_c3(el: Datapath, k: Constants, limit: int, *, registered: bool) -> None:
    """c3 = clip(mul_const(num, c3_from_l2)) -> ``ac_x`` (the Acos datapath's clipped input)."""
    nearest, one = k.cfg.round_nearest, k.one_u
    mc = k.c3_from_l2
    if mc.mant < 0:
        raise ValueError("c3_from_l2: negative constant not supported")
    el.add("c3_pre", lambda s: dict(drop(s, "numc"), c3v=rshift_round(s["numc"], mc.pre, nearest)))
    add_products(el, "c3m", [(lambda s: s["c3v"], const_mul_operand(k, mc, limit), mc.mant, "c3p")],
                 drop_keys=("c3v",))
    el.add("c3_post", lambda s: dict(drop(s, "c3p"), c3r=rshift_round(s["c3p"], mc.post, nearest)))
    add_selecting(el, "c3_clip", {"over": lambda s: s["c3r"] > one, "under": lambda s: s["c3r"] < -one},
                   lambda s, f: dict(drop(s, "c3r"), ac_x=Mux(f["over"], one,
                                                              Mux(f["under"], -one, s["c3r"]))),
                   registered=registered)


def add_c3_complements(el: Datapath, k: Constants, limit: int, *, registered: bool) -> None:
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
    operand = const_mul_operand(k, mc, 2 * limit)
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

    add_selecting(el, "c3_clip", {"minus_over": lambda s: s["cmr"] > two,
                                   "plus_over": lambda s: s["cpr"] > two},
                   clip, registered=registered)

