"""Circular CORDIC blocks: :class:`Atan2` (vectoring) and :class:`Rotate` (rotation).

Bit-exact hardware of ``model.cordic_atan2`` and ``model.cordic_rotate``
(``firmware_model/model.py``), parameterised by :class:`~ik5r.core.fxconfig.Constants`.
"""

from __future__ import annotations

from amaranth.hdl import Cat, Const, Mux, signed, unsigned

from ik5r.core.fxconfig import Constants

from ..datapath.stages import Datapath, GenericAdders, SharedStage, adders_for
from ..datapath.expr import asr, drop, leading_zeros, rshift_round, saturate, table_entry
from ..datapath.products import add_products
from .stream_block import StreamBlock, micro_steps

__all__ = ["Atan2", "Rotate", "add_atan2", "atan2_widths"]


def atan2_widths(k: Constants) -> dict:
    """Register widths of the vectoring datapath (see the bounds in :func:`add_atan2`)."""
    c = k.cfg
    return {
        "cx": signed(c.width + c.guard_bits + 3),
        "cy": signed(c.width + c.guard_bits + 3),
        "cz": signed((k.half_pi_z + sum(k.atan_table)).bit_length() + 2),
        "norm": unsigned((c.width - 1).bit_length()),
    }


def rotate_z_bound(k: Constants) -> int:
    """Bound of the rotation angle accumulator: below 2**(W-1+ag) + half_pi_z at the start, then
    moved by at most sum(atan_table)."""
    c = k.cfg
    return (1 << (c.width - 1 + c.angle_guard_bits)) + k.half_pi_z + sum(k.atan_table)


def cordic_unit(k: Constants, *, rotate: bool, adders=None) -> SharedStage:
    """The circular CORDIC micro-rotation as a functional unit, shared in the compact IK core.

    Keys ``cx``, ``cy``, ``cz`` and ``rotate``: vectoring (``rotate`` 0: turn towards y = 0, by
    the sign of y; :func:`add_atan2`) or rotation (``rotate`` 1: drive z to 0, by the sign of z;
    :class:`Rotate`). Its registers are wide enough for both (see their bounds). With ``rotate``
    a constant the step is exactly the vectoring or the rotation one; as a value (the shared unit)
    both in one: direction d = rotate ? z >= 0 : y < 0, then x -+ (y >> i), y +- (x >> i),
    z -+ step, which is each of them for its value of ``rotate``. ``adders``: the datapath's
    add/subtract mapping (generic when None).
    """
    add_sub = (adders or GenericAdders()).add_sub
    c = k.cfg
    xy = signed(c.width + c.guard_bits + 3)
    z_width = max(atan2_widths(k)["cz"].width, rotate_z_bound(k).bit_length() + 1)
    shapes = {"cx": xy, "cy": xy, "cz": signed(z_width), "rotate": unsigned(1)}

    def micro_rotation(s, i):
        xs, ys, z, mode = s["cx"], s["cy"], s["cz"], s["rotate"]
        step = table_entry(k.atan_table, i)
        if isinstance(mode, bool):
            if mode:
                neg = z[-1]       # z < 0: rotate clockwise
                return dict(s,
                            cx=add_sub(xs, asr(ys, i), ~neg),  # xs +- (ys >> i)
                            cy=add_sub(ys, asr(xs, i), neg),   # ys -+ (xs >> i)
                            cz=add_sub(z, step, ~neg))         # z +- step
            down = ys[-1]     # ys < 0: rotate the other way
            return dict(s,
                        cx=add_sub(xs, asr(ys, i), down),      # xs -+ (ys >> i)
                        cy=add_sub(ys, asr(xs, i), ~down),     # ys +- (xs >> i)
                        cz=add_sub(z, step, down))             # z -+ step
        down = Mux(mode, ~z[-1], ys[-1])
        return dict(s, cx=add_sub(xs, asr(ys, i), down), cy=add_sub(ys, asr(xs, i), ~down),
                    cz=add_sub(z, step, down))

    return SharedStage("cordic", micro_rotation,
                       {"cx": "cx", "cy": "cy", "cz": "cz", "rotate": rotate}, shapes)


def skewed_rotation(k: Constants, adders):
    """The rotation micro-rotations as ``iterations + 1`` stages ``fn(state, i)`` with the angle
    one step ahead of the vector: stage i takes z through micro-rotation i (while i <
    iterations) and (x, y) through micro-rotation i - 1 (from stage 1), by the sign of z_(i-1)
    that stage i - 1 copied into ``cneg`` (for y) and ``cpos`` (for x).

    The same arithmetic as ``cordic_unit(k, rotate=True)``, one stage later. Why: there, one
    flip-flop (the sign of z) steers three adders (x, y and z, ~110 LUTs), and its route was the
    pipelined Rotate's slowest path. Here the sign of z steers the z adder only; x and y read
    copies registered a stage later, one each (``cpos`` is the complement, so the two copies
    have different inputs and synthesis cannot merge them back into one). Pipelined only (``i``
    an int): one step per clock gains nothing from it. ``adders``: the datapath's add/subtract
    mapping.
    """
    add_sub = adders.add_sub
    count = k.cfg.iterations

    def step(s, i: int):
        xs, ys, z = s["cx"], s["cy"], s["cz"]
        out = dict(s, cneg=z[-1], cpos=~z[-1])
        if i < count:
            out["cz"] = add_sub(z, Const(k.atan_table[i]), ~z[-1])  # z -+ step
        else:
            out = drop(out, "cz", "cneg", "cpos")
        if i > 0:
            out["cx"] = add_sub(xs, asr(ys, i - 1), s["cpos"])  # xs -+ (ys >> i-1)
            out["cy"] = add_sub(ys, asr(xs, i - 1), s["cneg"])  # ys +- (xs >> i-1)
        return out

    return step, count + 1


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
    dp.add("at_coarse", _coarse(k, dp.adders.add_sub, y=y, x=x))
    byte_counts, normalise_shift_bytes, normalise_shift_fine = _normalisation(k)
    dp.add("at_lzc", byte_counts)
    dp.add("at_norm", normalise_shift_bytes)
    dp.add("at_norm_fine", normalise_shift_fine)
    dp.add_micro_steps("at_it", None, c.iterations, cordic_unit(k, rotate=False, adders=dp.adders))
    nearest = c.round_nearest

    def angle(s):
        # angle = rshift_round(z, angle_guard_bits); 0 for the zero vector.
        return {"angle": Mux(s["czero"], 0, rshift_round(s["cz"], c.angle_guard_bits, nearest))}

    keep_zero = {"zero": lambda s: s["czero"]} if zero else {}

    if not magnitude:
        def post(s):
            out = drop(s, "cx", "cy", "cz", "norm", "czero")
            out.update(angle(s))
            out.update({key: fn(s) for key, fn in keep_zero.items()})
            return out
        dp.add("at_angle", post)
        return

    _add_magnitude(dp, k, angle, keep_zero)


def _coarse(k: Constants, add_sub, *, y: str, x: str):
    """The coarse stage of :func:`add_atan2` (``add_sub``: the datapath's adders)."""
    def coarse(s):
        # Rotation by -+90 degrees into the right half-plane; zero flag.
        xv, yv = s[x], s[y]
        x_neg, y_neg = xv[-1], yv[-1]
        out = drop(s, x, y)
        # cx = x < 0 ? (y < 0 ? -y : y) : x, cy = x < 0 ? (y < 0 ? x : -x) : y, each as
        # 0 +- (a mux of x and y): the mux and the negation share the LUT before the carry chain
        # (a negation followed by a mux was the slowest path of the acos block).
        out["cx"] = add_sub(0, Mux(x_neg, yv, xv), x_neg & y_neg)
        out["cy"] = add_sub(0, Mux(x_neg, xv, yv), x_neg & ~y_neg)
        out["cz"] = Mux(x_neg, Mux(y_neg, Const(-k.half_pi_z), Const(k.half_pi_z)), Const(0))
        out["czero"] = (xv == 0) & (yv == 0)
        return out

    return coarse


def _normalisation(k: Constants):
    """The three normalisation stages of :func:`add_atan2`."""
    c = k.cfg
    width, guard = c.width, c.guard_bits
    # norm = max(0, W - 1 - bit_length(xs | ones_abs(ys))) in three stages, over bytes of
    # u = v[:W-1] (v = xs | ones_abs(ys)) padded at the LSB end with 1 0..0 to whole bytes (so a
    # zero u counts W - 1): each byte's zero flag and leading-zero count; then the first non-zero
    # byte from the top, and the shift by whole bytes; then the shift by the count in that byte.
    # A leading-zero tree over all W - 1 bits and a shift by norm in one stage were the slowest
    # paths of the block.
    pad = 8 - (width - 1) % 8
    norm_bits = atan2_widths(k)["norm"].width
    groups = (width - 1 + pad) // 8

    def byte_counts(s):
        xs, ys = s["cx"], s["cy"]
        ones_abs = Mux(ys[-1], ~ys, ys)
        v = xs[:width] | ones_abs[:width]
        padded = Cat(Const(1 << (pad - 1), pad), v[:width - 1])
        tops = [padded[8 * (groups - 1 - j):8 * (groups - j)] for j in range(groups)]
        return dict(s, ntop=v[width - 1], nzg=Cat(*(t.any() for t in tops)),
                    gcnt=Cat(*(leading_zeros(t)[:3] for t in tops)))

    def normalise_shift_bytes(s):
        top, nonzero, counts = s["ntop"], s["nzg"], s["gcnt"]
        index, count = Const(groups - 1), counts[3 * (groups - 1):]
        for j in reversed(range(groups - 1)):
            index = Mux(nonzero[j], j, index)
            count = Mux(nonzero[j], counts[3 * j:3 * j + 3], count)
        index = Mux(top, 0, index)
        out = drop(s, "ntop", "nzg", "gcnt")
        out["norm"] = Mux(top, 0, Cat(count, index[:norm_bits - 3]))
        by = Cat(Const(0, 3), index)
        out["cx"] = (s["cx"] << by).shift_left(guard)
        out["cy"] = (s["cy"] << by).shift_left(guard)
        return out

    def normalise_shift_fine(s):
        by = s["norm"][:3]
        return dict(s, cx=s["cx"] << by, cy=s["cy"] << by)

    return byte_counts, normalise_shift_bytes, normalise_shift_fine


def _add_magnitude(dp: Datapath, k: Constants, angle, keep_zero):
    """The magnitude stages of :func:`add_atan2`, the angle (``angle(state)``) and the zero
    flag (``keep_zero``) computed beside its multiplier."""
    c = k.cfg
    width, guard, nearest = c.width, c.guard_bits, c.round_nearest
    # magnitude = sat(rshift_round((xs >> g) * inv_gain, inv_gain_frac + norm)).
    # Rounded: floor((p / 2**(s-1) + 1) / 2) = ((p >> (s-1)) + 1) >> 1, s - 1 = inv_gain_frac - 1 + norm >= 0.
    def product_side(s):
        out = angle(s)
        out.update({key: fn(s) for key, fn in keep_zero.items()})
        out["mzero"] = s["czero"]
        return out

    add_products(dp, "at_mag", [(lambda s: asr(s["cx"], guard)[:width + 1],
                                 unsigned(width + 1), k.inv_gain, "mag_p")],
                 parallel=product_side, drop_keys=("cx", "cy", "cz", "czero"))
    shift_const = k.inv_gain_frac - 1 if nearest else k.inv_gain_frac

    def denormalise_coarse(s):
        out = drop(s, "mag_p")
        out["mag_t"] = s["mag_p"].shift_right(shift_const) >> Cat(Const(0, 3), s["norm"][3:])
        return out

    def denormalise_fine(s):
        out = drop(s, "norm")
        out["mag_t"] = s["mag_t"] >> s["norm"][:3]
        return out

    def round_saturate(s):
        t = s["mag_t"]
        out = drop(s, "mag_t", "mzero")
        if nearest:
            # (t + 1) >> 1 > word_max  <=>  t >= 2**W - 1 (a comparison parallel to the adder).
            over = t >= (1 << width) - 1
            value = (t + 1).shift_right(1)
        else:
            over = t > k.word_max
            value = t
        out["magnitude"] = Mux(s["mzero"], 0, Mux(over, k.word_max, value[:width]))
        return out

    dp.add("at_denorm", denormalise_coarse)
    dp.add("at_denorm_fine", denormalise_fine)
    dp.add("at_round", round_saturate)


class Atan2(StreamBlock):
    """Full-circle ``atan2(y, x)`` of two words by CORDIC vectoring, bit-exact to
    ``model.cordic_atan2``.

    The vector is rotated by -+90 degrees into the right half-plane, normalised (block floating
    point: a ones'-complement priority encoder finds the shift ``norm`` that puts the top bit of
    ``xs | ones_abs(ys)`` at bit W-2) and shifted up by ``guard_bits`` more, then
    ``iterations`` micro-rotations (arithmetic-shift, floor) drive y to 0 while an accumulator
    sums ``atan_table``. The angle is rounded off its ``angle_guard_bits``; the magnitude is
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
                 magnitude: bool = True, dsp: str = "generic", rotations_per_stage: int = 1):
        if not isinstance(magnitude, bool):
            raise TypeError(f"magnitude must be a bool, got {magnitude!r}")
        if isinstance(constants, Constants):
            c = constants.cfg
            dp = Datapath("atan2", adders=adders_for(dsp), inputs=("y", "x"),
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
        :data:`~ik5r.hdl.modes.DSPS`).
    tag_width : int
        Width of the optional ``tag`` field (0: none).
    """

    def __init__(self, *, constants: Constants, arch: str, tag_width: int = 0, dsp: str = "generic",
                 rotations_per_stage: int = 1):
        if isinstance(constants, Constants):
            k, c = constants, constants.cfg
            dp = self.chain(k, skewed=arch == "pipelined", adders=adders_for(dsp),
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
        :func:`skewed_rotation` (one stage more, a shorter critical path), else on
        ``cordic_unit(k, rotate=True)`` (one step per clock; shareable with vectoring in
        :class:`~ik5r.hdl.pipelined.core.IKCore` compact). ``steps_per_stage``: micro-rotations
        per pipeline stage (None: the context's, :func:`~ik5r.hdl.datapath.stages.steps_per_stage`).

        Bounds (W = width, g = guard_bits): after the quadrant step |x|, |y| <= 2**(W-1);
        times 1/K < 0.61 with g guard bits, |xs|, |ys| < 0.61 * 2**(W-1+g) + 1; the
        micro-rotations multiply the length by K_n (< 1.65) plus one LSB per step, so
        |xs|, |ys| < sqrt(2) * 2**(W-1+g) * 1.01: signed(W+g+3) has two spare bits. The angle
        accumulator starts below 2**(W-1+ag) + half_pi_z and moves by at most sum(atan_table).
        """
        c = k.cfg
        width, guard, nearest = c.width, c.guard_bits, c.round_nearest
        dp = Datapath("rotate", adders=adders, inputs=("x", "y", "angle"),
                      outputs=("x", "y", "saturated"), steps_per_stage=steps_per_stage)
        z_bound = rotate_z_bound(k)
        dp.declare(cx=signed(width + guard + 3), cy=signed(width + guard + 3),
                   cz=signed(z_bound.bit_length() + 1),
                   rx=signed(width + 1), ry=signed(width + 1))

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
            out["cz"] = Mux(up, z - k.half_pi_z, Mux(down, z + k.half_pi_z, z))
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

        dp.add("ro_gain_round", gain_round)
        dp.mark("micro_rotations")
        if skewed:
            dp.add_micro_steps("ro_it", *skewed_rotation(k, dp.adders))
        else:
            dp.add_micro_steps("ro_it", None, c.iterations, cordic_unit(k, rotate=True, adders=dp.adders))
        dp.add("ro_unguard", unguard)
        dp.add("ro_clip", clip)
        return dp

    def _inputs(self, payload):
        return {"x": payload.x, "y": payload.y, "angle": payload.angle}

    def _outputs(self, state):
        return {"x": state["x"], "y": state["y"], "saturated": state["saturated"]}
