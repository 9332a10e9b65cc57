"""The IK core's orientation checks (``model.frame_is_bad``, ``model.off_plane``), computed beside
the dot products of the joint-5 step (:mod:`.ik_datapath`)."""

from __future__ import annotations

from amaranth.hdl import signed

from ik5r.core import status as S
from ik5r.core.fxconfig import Constants

from .expr import drop
from .ik_steps import flag

__all__ = ["orientation_specs", "orientation_operands", "orientation_sums", "orientation_terms",
           "orientation_flag"]
# Products of check words (the top 17 bits of a unit word: one 17 x 17 partial product each), computed
# beside the dot products: 15 for the n, o, a frame (n.n, o.o, n.o, n x o), 2 for the approach's
# component normal to the arm's plane (ay c1 - ax s1). Keys ``ck*``.

_FRAME_PAIRS = (("nx", "nx"), ("ny", "ny"), ("nz", "nz"), ("ox", "ox"), ("oy", "oy"), ("oz", "oz"),
                ("nx", "ox"), ("ny", "oy"), ("nz", "oz"), ("ny", "oz"), ("nz", "oy"), ("nz", "ox"),
                ("nx", "oz"), ("nx", "oy"), ("ny", "ox"))


def orientation_specs(words: Constants) -> list:
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


def orientation_operands(s, words: Constants) -> dict:
    """The approach's check words (n x o is compared with them), kept beside the products."""
    shift = words.cfg.internal_guard_bits + words.check_shift
    return {f"cka{axis}": s[f"a{axis}"].shift_right(shift) for axis in "xyz"}


def orientation_sums(s) -> dict:
    """First adder level: two-term sums and the cross product's differences."""
    out = drop(s, *(f"ck{i}" for i in (0, 1, 3, 4, 6, 7, 9, 10, 11, 12, 13, 14, 15, 16)))
    out.update(ckn=s["ck0"] + s["ck1"], cko=s["ck3"] + s["ck4"], ckno=s["ck6"] + s["ck7"],
               ckcx=s["ck9"] - s["ck10"], ckcy=s["ck11"] - s["ck12"], ckcz=s["ck13"] - s["ck14"],
               ckpl=s["ck15"] - s["ck16"])
    return out


def orientation_terms(s, words: Constants) -> dict:
    """Second adder level: the third terms of the dot products, n x o - a."""
    frac = words.check_frac
    out = drop(s, "ck2", "ck5", "ck8", "ckax", "ckay", "ckaz")
    out.update(ckn=s["ckn"] + s["ck2"], cko=s["cko"] + s["ck5"], ckno=s["ckno"] + s["ck8"],
               **{f"ckc{axis}": s[f"ckc{axis}"] - s[f"cka{axis}"].shift_left(frac) for axis in "xyz"})
    return out


def orientation_flag(s, words: Constants):
    """(state without the check keys, BAD_ORIENTATION status bits): off the plane, or (with roll)
    a frame error beyond the tolerance."""
    ki = words.internal

    def beyond(value, centre, k):
        return (value > centre + k.check_tol_c2) | (value < centre - k.check_tol_c2)

    frame = (beyond(s["ckn"], words.check_one_c2, words) | beyond(s["cko"], words.check_one_c2, words)
             | beyond(s["ckno"], 0, words)
             | beyond(s["ckcx"], 0, words) | beyond(s["ckcy"], 0, words) | beyond(s["ckcz"], 0, words))
    bad = beyond(s["ckpl"], 0, ki) | (s["roll"] & frame)
    return drop(s, "ckn", "cko", "ckno", "ckcx", "ckcy", "ckcz", "ckpl"), flag(bad, S.BAD_ORIENTATION)

