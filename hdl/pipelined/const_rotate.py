"""The rotation of a constant vector as a datapath chain: the pipelined core's unit of a
``cordic_rotate`` whose x and y are constants (the IK's rotation of (1, 0))."""

from __future__ import annotations

from amaranth.hdl import Mux

from ik5r.core import fixedpoint

from ..blocks.cordic import Rotate
from ..datapath.expr import drop
from ..datapath.stages import Datapath

__all__ = ["rotate_const_chain"]


def rotate_const_chain(k, vector: tuple[int, int], *, skewed: bool, adders) -> Datapath:
    """``model.cordic_rotate(*vector, angle)`` of a constant vector -> x, y, saturated. The
    quadrant step and the 1/K gain of a constant vector are constants: two stages (the compares
    registered first) replace the Rotate block's quadrant, coarse and multiplier stages; the
    micro-rotations, rounding and clipping are the Rotate block's own stages (``skewed``: see
    :meth:`Rotate.chain`; else on the shared CORDIC unit)."""
    c = k.cfg
    tail = Rotate.chain(k, skewed=skewed, adders=adders).part("micro_rotations")
    x0, y0 = vector
    shift = k.inv_gain_frac - c.guard_bits

    def gained(x, y):
        return (fixedpoint.rshift_round(x * k.inv_gain, shift, c.round_nearest),
                fixedpoint.rshift_round(y * k.inv_gain, shift, c.round_nearest))

    cases = {"up": gained(-y0, x0), "down": gained(y0, -x0), "none": gained(x0, y0)}
    h = k.half_pi_z

    def compares(s):
        z = s["angle"].shift_left(c.angle_guard_bits)
        return dict(drop(s, "angle"), qz=z, up=z > h, down=z < -h)

    def quadrant(s):
        z, up, down = s["qz"], s["up"], s["down"]
        out = drop(s, "qz", "up", "down")
        out["cx"] = Mux(up, cases["up"][0], Mux(down, cases["down"][0], cases["none"][0]))
        out["cy"] = Mux(up, cases["up"][1], Mux(down, cases["down"][1], cases["none"][1]))
        out["cz"] = z + Mux(up, -h, Mux(down, h, 0))
        return out

    chain = Datapath("rotate_const", adders=adders, inputs=("angle",), outputs=("x", "y", "saturated"))
    chain.shapes = dict(tail.shapes)
    chain.add("ro_const_cmp", compares)
    chain.add("ro_const", quadrant)
    chain.stages.extend(tail.stages)
    return chain
