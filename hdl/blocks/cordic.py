"""Circular CORDIC blocks: :class:`Atan2` (vectoring) and :class:`Rotate` (rotation).

Bit-exact hardware of ``model.cordic_atan2`` and ``model.cordic_rotate``
(``firmware_model/model.py``), parameterised by :class:`~ik5r.core.fxconfig.Constants`.
"""

from __future__ import annotations

from amaranth.hdl import Mux, signed, unsigned

from ik5r.core.fxconfig import Constants
from ik5r.core.modes import Arch, Block, Dsp

from ..datapath.stages import Datapath, adders_for
from ..datapath.expr import drop, rshift_round, saturate
from ..datapath.products import add_products
from .cordic_steps import (add_magnitude, atan2_coarse, atan2_normalisation, atan2_widths, cordic_step,
                           rotate_z_bound, skewed_rotation, vectoring_angle)
from .stream_block import StreamBlock, micro_steps

__all__ = ["Atan2", "Rotate", "add_atan2", "atan2_widths"]


def add_atan2(dp: Datapath, k: Constants, *, y: str, x: str, magnitude: bool, zero: bool):
    """Append the stages of ``model.cordic_atan2(state[y], state[x])`` to ``dp``.

    Consumes ``y`` and ``x`` (signed words); produces ``angle`` (word, Q.frac_angle), and when
    asked ``magnitude`` (word, the inputs' format) and ``zero`` (1 bit). Other keys pass through.

    Bounds (W = width, g = guard_bits): after the coarse rotation 0 <= xs <= 2**(W-1) and
    |ys| <= 2**(W-1); the normalisation puts the top bit of ``xs | ones_abs(ys)`` at W-2 (or
    leaves it at W-1 when norm = 0), so after the shift by norm + g, |xs|, |ys| <= 2**(W-1+g).
    The micro-rotations grow the vector by at most K_n * sqrt(2) < 2.33 (plus one LSB per step
    from the floors), so |xs|, |ys| < 2**(W+1+g): signed(W+g+3) has a spare bit. The angle
    accumulator holds at most half_pi_z + sum(atan_table). xs never decreases, so it stays >= 0,
    and (xs >> g) < 2**(W+1) is the unsigned multiplicand of 1/K.
    """
    c = k.cfg
    dp.declare(**atan2_widths(k))
    dp.add("at_coarse", atan2_coarse(k, dp.adders.add_sub, y=y, x=x))
    byte_counts, normalise_shift_bytes, normalise_shift_fine = atan2_normalisation(k)
    dp.add("at_lzc", byte_counts)
    dp.add("at_norm", normalise_shift_bytes)
    dp.add("at_norm_fine", normalise_shift_fine)
    dp.add_micro_steps("at_it", cordic_step(k, rotate=False, adders=dp.adders), c.iterations)

    def angle(s):
        # angle = rshift_round(z, angle_guard_bits); 0 for the zero vector.
        return {"angle": Mux(s["czero"], 0, vectoring_angle(k, s))}

    keep_zero = {"zero": lambda s: s["czero"]} if zero else {}

    if not magnitude:
        def post(s):
            out = drop(s, "cx", "cy", "cz", "cd", "norm", "czero")
            out.update(angle(s))
            out.update({key: fn(s) for key, fn in keep_zero.items()})
            return out
        dp.add("at_angle", post)
        return

    add_magnitude(dp, k, angle, keep_zero)


class Atan2(StreamBlock):
    """Full-circle ``atan2(y, x)`` of two words by CORDIC vectoring, bit-exact to
    ``model.cordic_atan2``.

    The vector is rotated by -+90 degrees into the right half-plane, normalised (block floating
    point: a ones'-complement priority encoder finds the shift ``norm`` that puts the top bit of
    ``xs | ones_abs(ys)`` at bit W-2) and shifted up by ``guard_bits`` more, then
    ``iterations`` micro-rotations (arithmetic-shift, floor) drive y to 0 while an accumulator
    sums ``atan_table`` (pipelined: up to the first step that is an exact power of two, and from
    there on only the directions are kept, 1 bit a stage, and subtracted, doubled, in one adder at
    the end: :func:`~ik5r.hdl.blocks.cordic_steps.angle_tail`; the same integer). The angle is
    rounded off its ``angle_guard_bits``; the magnitude is
    ``(xs >> guard_bits) * inv_gain`` rounded-shifted by ``31 + norm`` and saturated.

    Payloads (W = ``constants.cfg.width``; Q m.n means n fraction bits, m + n = W):

    * ``i.payload.y``, ``i.payload.x``: ``signed(W)``, any common format Q m.n (atan2 is
      scale-free).
    * ``o.payload.angle``: ``signed(W)``, Q(W - frac_angle).frac_angle radians in [-pi, pi].
    * ``o.payload.magnitude`` (only if ``magnitude``): ``signed(W)``, the inputs' format Q m.n,
      ``sqrt(x**2 + y**2)`` saturated to the word maximum.
    * ``o.payload.zero``: 1 bit, set iff ``x == y == 0`` (then angle = magnitude = 0).
    * ``tag`` (only if ``tag_width``): ``unsigned(tag_width)``, carried unchanged.

    Timing: ``latency`` cycles from the input transfer to the output valid: 4 + iterations + 1
    stages without the magnitude, 4 + iterations + 7 with it (coarse rotation, leading-zero count
    per byte, normalising shift by whole bytes, then by the rest, micro-rotations, then the angle
    rounding in parallel with the 1/K multiplier (operand register, DSP partial products, two adder
    levels), the de-normalising shift (two stages) and the magnitude rounding/saturation), plus 3
    for the output FIFO of the pipelined architecture and the register in front of it (each
    config's figures: the port map JSON, ``latency_cycles``). Throughput
    (``cycles_per_result``): ``"pipelined"`` one result per cycle; the pipeline never stalls, its
    results queue in an output FIFO while ``o`` is held, and ``i.ready`` drops only when
    ``capacity`` items are inside (see
    :class:`~ik5r.hdl.blocks.stream_block.StreamBlock`); ``"iterative"`` one micro-rotation per cycle and one
    item in flight, a new item accepted when idle or as the previous result leaves: one result every
    ``latency`` cycles.

    Parameters
    ----------
    constants : Constants
        Widths, iterations, guard bits, rounding and the atan table.
    arch : ``"pipelined"`` or ``"iterative"``
    tag_width : int
        Width of the optional ``tag`` field (0: none).
    magnitude : bool
        Whether to compute and output ``magnitude``.
    """

    def __init__(self, *, constants: Constants, arch: str, tag_width: int = 0,
                 magnitude: bool = True, dsp: str = Dsp.GENERIC, rotations_per_stage: int = 1):
        if not isinstance(magnitude, bool):
            raise TypeError(f"magnitude must be a bool, got {magnitude!r}")
        if isinstance(constants, Constants):
            c = constants.cfg
            dp = Datapath(Block.ATAN2, adders=adders_for(dsp), inputs=("y", "x"),
                          steps_per_stage=micro_steps(arch, rotations_per_stage),
                          outputs=("angle", "magnitude", "zero") if magnitude else ("angle", "zero"))
            add_atan2(dp, constants, y="y", x="x", magnitude=magnitude, zero=True)
            word = signed(c.width)
            in_fields = {"y": (word, None, "ordinate, same format as x"),
                         "x": (word, None, "abscissa, same format as y")}
            out_fields = {"angle": (word, c.frac_angle, "atan2(y, x), radians, in [-pi, pi]")}
            if magnitude:
                out_fields["magnitude"] = (word, None,
                                           "sqrt(x^2 + y^2), format of x and y, saturated")
            out_fields["zero"] = (unsigned(1), 0, "x == y == 0 (angle and magnitude are 0)")
        else:
            dp = in_fields = out_fields = None
        self.magnitude = magnitude
        self.options = {"magnitude": magnitude}
        super().__init__(constants=constants, arch=arch, tag_width=tag_width, in_fields=in_fields,
                         out_fields=out_fields, datapath=dp, dsp=dsp, rotations_per_stage=rotations_per_stage)

    def _inputs(self, payload):
        return {"y": payload.y, "x": payload.x}

    def _outputs(self, state):
        out = {"angle": state["angle"], "zero": state["zero"]}
        if self.magnitude:
            out["magnitude"] = state["magnitude"]
        return out


class Rotate(StreamBlock):
    """Rotation of the vector (x, y) by an angle, by CORDIC, bit-exact to ``model.cordic_rotate``.

    The angle (moved to the accumulator format by ``angle_guard_bits``) is brought within
    +-pi/2 by a rotation of the vector by +-90 degrees; the vector is multiplied by
    ``inv_gain`` (1/K, gain compensation on the input) and rounded to ``guard_bits`` extra
    fraction bits; ``iterations`` micro-rotations (arithmetic-shift, floor) drive the angle to 0;
    the results are rounded off the guard bits and saturated to words.

    Payloads (W = ``constants.cfg.width``):

    * ``i.payload.x``, ``i.payload.y``: ``signed(W)``, any common format Q m.n.
    * ``i.payload.angle``: ``signed(W)``, Q(W - frac_angle).frac_angle radians,
      |angle| <= pi + a few LSB for a converged result (any word gives the model's result).
    * ``o.payload.x``, ``o.payload.y``: ``signed(W)``, the inputs' format, saturated.
    * ``o.payload.saturated``: 1 bit, set iff x or y was clipped to the word range.
    * ``tag`` (only if ``tag_width``): ``unsigned(tag_width)``, carried unchanged.

    Timing: ``latency`` = 8 + adder-tree levels of the 1/K multiplier (2 up to 33-bit words) +
    iterations stages (angle compare, quadrant rotation, 1/K multiplier (operand register, DSP
    partial products, adder levels), gain rounding, micro-rotations (pipelined: iterations + 1
    skewed stages, see :func:`skewed_rotation`), guard rounding, saturation), plus 3 for the
    output FIFO of the pipelined architecture and the register in front of it (iterative: one
    micro-rotation per clock, iterations stages). Throughput: ``"pipelined"`` one result per
    cycle, never stalling: results queue in the output FIFO while ``o`` is held, and ``i.ready``
    drops only when ``capacity`` items are inside (see
    :class:`~ik5r.hdl.blocks.stream_block.StreamBlock`); ``"iterative"`` one result every ``latency`` cycles (one
    micro-rotation per cycle).

    Parameters
    ----------
    constants : Constants
    arch : ``"pipelined"`` or ``"iterative"``
    dsp : ``"generic"`` or ``"ecp5"``
        Pipelined arch: the partial products as ``*`` or as ECP5 ``MULT18X18D`` instances using
        their input and output registers, the micro-rotations as ``CCU2C`` chains (see
        :data:`~ik5r.core.modes.DSPS`).
    tag_width : int
        Width of the optional ``tag`` field (0: none).
    """

    def __init__(self, *, constants: Constants, arch: str, tag_width: int = 0, dsp: str = Dsp.GENERIC,
                 rotations_per_stage: int = 1):
        if isinstance(constants, Constants):
            k, c = constants, constants.cfg
            dp = self.chain(k, skewed=arch == Arch.PIPELINED, adders=adders_for(dsp),
                            steps_per_stage=micro_steps(arch, rotations_per_stage))
            word = signed(c.width)
            in_fields = {"x": (word, None, "abscissa, same format as y"),
                         "y": (word, None, "ordinate, same format as x"),
                         "angle": (word, c.frac_angle, "rotation angle, radians")}
            out_fields = {"x": (word, None, "rotated abscissa, format of the inputs, saturated"),
                          "y": (word, None, "rotated ordinate, format of the inputs, saturated"),
                          "saturated": (unsigned(1), 0, "x or y clipped to the word range")}
        else:
            dp = in_fields = out_fields = None
        super().__init__(constants=constants, arch=arch, tag_width=tag_width, in_fields=in_fields,
                         out_fields=out_fields, datapath=dp, dsp=dsp, rotations_per_stage=rotations_per_stage)

    @staticmethod
    def chain(k: Constants, *, skewed: bool, adders=None, steps_per_stage: int | None = None) -> Datapath:
        """The rotation datapath as a chain: inputs ``x``, ``y``, ``angle``; outputs ``x``, ``y``,
        ``saturated``; split point ``"micro_rotations"`` in front of the micro-rotations (which
        read ``cx``, ``cy``, ``cz``: the IK core's constant rotations start there).
        ``adders``: the add/subtract mapping (generic when None). ``skewed`` (pipelined): the
        micro-rotations as
        :func:`skewed_rotation` (one stage more, a shorter critical path), else
        ``cordic_step(k, rotate=True)`` (one step per clock). ``steps_per_stage``: micro-rotations
        per pipeline stage (None: the context's, :func:`~ik5r.hdl.datapath.stages.steps_per_stage`).

        Bounds (W = width, g = guard_bits): after the quadrant step |x|, |y| <= 2**(W-1);
        times 1/K < 0.61 with g guard bits, |xs|, |ys| < 0.61 * 2**(W-1+g) + 1; the
        micro-rotations multiply the length by K_n (< 1.65) plus one LSB per step, so
        |xs|, |ys| < sqrt(2) * 2**(W-1+g) * 1.01: signed(W+g+3) has two spare bits. The angle
        accumulator starts below 2**(W-1+ag) + half_pi_z and moves by at most sum(atan_table).
        """
        c = k.cfg
        width, guard = c.width, c.guard_bits
        dp = Datapath(Block.ROTATE, adders=adders, inputs=("x", "y", "angle"),
                      outputs=("x", "y", "saturated"), steps_per_stage=steps_per_stage)
        z_bound = rotate_z_bound(k)
        dp.declare(cx=signed(width + guard + 3), cy=signed(width + guard + 3),
                   cz=signed(z_bound.bit_length() + 1),
                   rx=signed(width + 1), ry=signed(width + 1))
        _add_rotation_front(dp, k)
        dp.mark("micro_rotations")
        if skewed:
            dp.add_micro_steps("ro_it", *skewed_rotation(k, dp.adders))
        else:
            dp.add_micro_steps("ro_it", cordic_step(k, rotate=True, adders=dp.adders), c.iterations)
        unguard, clip = _rotation_back(k)
        dp.add("ro_unguard", unguard)
        dp.add("ro_clip", clip)
        return dp

    def _inputs(self, payload):
        return {"x": payload.x, "y": payload.y, "angle": payload.angle}

    def _outputs(self, state):
        return {"x": state["x"], "y": state["y"], "saturated": state["saturated"]}


def _add_rotation_front(dp: Datapath, k: Constants):
    """The stages of :meth:`Rotate.chain` before the micro-rotations: the angle within +-pi/2 by
    a quarter turn of the vector, then the vector times 1/K rounded to the guard bits."""
    c = k.cfg
    width, guard, nearest = c.width, c.guard_bits, c.round_nearest

    def quadrant(s):
        z = s["angle"].shift_left(c.angle_guard_bits)
        out = drop(s, "angle")
        out.update(rz=z, up=z > k.half_pi_z, down=z < -k.half_pi_z)
        return out

    def coarse(s):
        x, y, z, up, down = s["x"], s["y"], s["rz"], s["up"], s["down"]
        out = drop(s, "x", "y", "rz", "up", "down")
        out["rx"] = Mux(up, -y, Mux(down, y, x))
        out["ry"] = Mux(up, x, Mux(down, -x, y))
        out["cz"] = z + Mux(up, -k.half_pi_z, Mux(down, k.half_pi_z, 0))
        return out

    dp.add("ro_quadrant", quadrant)
    dp.add("ro_coarse", coarse)
    operand = signed(width + 1)
    add_products(dp, "ro_gain", [(lambda s: s["rx"], operand, k.inv_gain, "gx"),
                                 (lambda s: s["ry"], operand, k.inv_gain, "gy")],
                 drop_keys=("rx", "ry"))
    shift = k.inv_gain_frac - guard

    def gain_round(s):
        out = drop(s, "gx", "gy")
        out["cx"] = rshift_round(s["gx"], shift, nearest)
        out["cy"] = rshift_round(s["gy"], shift, nearest)
        return out

    dp.add("ro_gain_round", gain_round)


def _rotation_back(k: Constants):
    """The stages of :meth:`Rotate.chain` after the micro-rotations: round off the guard bits,
    then saturate to words."""
    width, guard, nearest = k.cfg.width, k.cfg.guard_bits, k.cfg.round_nearest

    def unguard(s):
        out = drop(s, "cx", "cy", "cz", "cneg", "cpos")
        out["ox"] = rshift_round(s["cx"], guard, nearest)
        out["oy"] = rshift_round(s["cy"], guard, nearest)
        return out

    def clip(s):
        out = drop(s, "ox", "oy")
        xo, sat_x = saturate(s["ox"], width)
        yo, sat_y = saturate(s["oy"], width)
        out.update(x=xo, y=yo, saturated=sat_x | sat_y)
        return out

    return unguard, clip
