"""The steps the CORDIC blocks of :mod:`ik5r.hdl.blocks.cordic` are made of: the micro-rotation
(one step per clock, and skewed for the pipelined rotation), the
register widths and bounds, and the vectoring datapath's coarse rotation, normalisation and
magnitude stages. :mod:`ik5r.hdl.blocks.cordic` composes them into :class:`Atan2` and
:class:`Rotate` and their chains.
"""

from __future__ import annotations

from amaranth.hdl import Cat, Const, Mux, signed, unsigned

from ik5r.core.fxconfig import Constants

from ..datapath.adders import GenericAdders
from ..datapath.expr import asr, drop, leading_zeros, rshift_round, table_entry
from ..datapath.products import add_products
from ..datapath.stages import Datapath


def atan2_widths(k: Constants) -> dict:
    """Register widths of the vectoring datapath (see the bounds in :func:`~ik5r.hdl.blocks.cordic.add_atan2`)."""
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


def angle_tail(k: Constants) -> int:
    """The first vectoring micro-rotation whose angle step, and every later one's, is an exact
    power of two, ``atan_table[i] == 2**(zf - i)`` (zf: the accumulator's fraction bits); the
    iteration count when there is none. From there on the pipelined atan2 keeps the rotation
    directions instead of adding their steps (see :func:`cordic_step`)."""
    c = k.cfg
    zf = c.frac_angle + c.angle_guard_bits
    start = len(k.atan_table)
    while start > 1 and start - 1 <= zf and k.atan_table[start - 1] == 1 << (zf - start + 1):
        start -= 1
    return start


def tail_directions_weight(k: Constants) -> int:
    """The weight (a left shift) of the lowest bit of ``cd``: the last micro-rotation's step."""
    c = k.cfg
    return c.frac_angle + c.angle_guard_bits - (len(k.atan_table) - 1)


def tail_offset(k: Constants) -> int:
    """What the atan2 accumulator takes at :func:`angle_tail` in place of that step: every tail
    step added (the directions' doubled steps come off at the end) and the rounding's half LSB."""
    g = k.cfg.angle_guard_bits
    half = 1 << (g - 1) if k.cfg.round_nearest and g > 0 else 0
    return sum(k.atan_table[angle_tail(k):]) + half


def vectoring_y_widths(k: Constants) -> list[int]:
    """Signed width of the vectoring y after each micro-rotation i (entry i: y_(i+1)), at most
    the register's. Bound (W = width, g = guard_bits, K < 1.6468 the gain, r0 the length after the
    normalisation: 2**(W-3+g) <= r0 <= sqrt(2) * 2**(W-1+g)): each step is an exact scaled
    rotation by atan(2**-i) plus a floor error below sqrt(2), so the state is K_i r0 at the
    residual angle phi_i plus an error below e_i = sqrt(2) K i. A direction differs from the sign of
    phi_i only where K_i r0 |sin phi_i| <= e_i, so |phi_i| <= eta = (pi/2) e_n / r0_min, and otherwise |phi_i| shrinks to
    ||phi_i| - atan(2**-i)|; with atan(2**-(i-1)) <= 2 atan(2**-i) and |phi_0| <= pi/2 (x >= 0
    after the coarse step) that gives |phi_(i+1)| <= atan(2**-i) + eta. So |y_(i+1)| <=
    K sqrt(2) 2**(W-1+g) (atan(2**-i) + eta) + e_(i+1): taken here with a 1 % margin and 2 LSB."""
    import math

    c = k.cfg
    full = c.width + c.guard_bits + 3
    n, gain = len(k.atan_table), 1.6468
    r_max, r_min = math.sqrt(2) * 2.0 ** (c.width - 1 + c.guard_bits), 2.0 ** (c.width - 3 + c.guard_bits)
    eta = (math.pi / 2) * math.sqrt(2) * gain * n / r_min     # K_i >= 1 under the sine
    widths = []
    for i in range(n):
        bound = gain * r_max * (math.atan(2.0 ** -i) + eta) + math.sqrt(2) * gain * (i + 1)
        widths.append(min(full, math.ceil(bound * 1.01 + 2).bit_length() + 1))
    return widths


def cordic_step(k: Constants, *, rotate: bool, adders=None):
    """The circular CORDIC micro-rotation ``fn(state, i)`` on the keys ``cx``, ``cy``, ``cz``:
    vectoring (``rotate`` False: turn towards y = 0, by the sign of y;
    :func:`~ik5r.hdl.blocks.cordic.add_atan2`) or rotation (``rotate`` True: drive z to 0, by the
    sign of z; :class:`~ik5r.hdl.blocks.cordic.Rotate`). ``adders``: the datapath's add/subtract
    mapping (generic when None).
    """
    add_sub = (adders or GenericAdders()).add_sub

    def micro_rotation(s, i):
        xs, ys, z = s["cx"], s["cy"], s["cz"]
        step = table_entry(k.atan_table, i)
        if rotate:
            neg = z[-1]       # z < 0: rotate clockwise
            return dict(s,
                        cx=add_sub(xs, asr(ys, i), ~neg),  # xs +- (ys >> i)
                        cy=add_sub(ys, asr(xs, i), neg),   # ys -+ (xs >> i)
                        cz=add_sub(z, step, ~neg))         # z +- step
        down = ys[-1]     # ys < 0: rotate the other way
        out = dict(s, cx=add_sub(xs, asr(ys, i), down))  # xs -+ (ys >> i)
        if isinstance(i, int):
            # ys +- (xs >> i) fits y_widths[i] bits (its bound): so does its value modulo
            # 2**y_widths[i], which only the operands' low bits make.
            w = y_widths[i]
            out["cy"] = add_sub(ys[:w].as_signed(), asr(xs, i)[:w].as_signed(), ~down)[:w].as_signed()
        else:
            out["cy"] = add_sub(ys, asr(xs, i), ~down)        # ys +- (xs >> i)
        if not isinstance(i, int) or i < tail:
            out["cz"] = add_sub(z, step, down)             # z -+ step
        elif i == tail:
            # The tail's steps are 2**(zf - i): z_n = z_tail + sum(steps) - 2 * (the directions
            # as a binary number). The sum (and the rounding's half) goes in now, the directions'
            # bits are kept (newest lowest) and come off in one subtraction at the angle stage:
            # one adder instead of one per micro-rotation, the same integer.
            out["cz"] = z + tail_offset(k)
            out["cd"] = down
        else:
            out["cd"] = Cat(down, s["cd"])
        return out

    tail = angle_tail(k) if not rotate else None
    y_widths = vectoring_y_widths(k) if not rotate else None
    return micro_rotation


def vectoring_angle(k: Constants, s):
    """The atan2 angle ``rshift_round(z_n, angle_guard_bits)`` of the state after the
    micro-rotations (see :func:`cordic_step`): z_n and the rounding's half are ``cz`` less the
    tail's directions doubled, when the pipelined build kept them (``cd``)."""
    c = k.cfg
    if "cd" not in s:
        return rshift_round(s["cz"], c.angle_guard_bits, c.round_nearest)
    doubled = s["cd"].as_unsigned().shift_left(tail_directions_weight(k) + 1)
    return (s["cz"] - doubled).shift_right(c.angle_guard_bits)


def skewed_rotation(k: Constants, adders):
    """The rotation micro-rotations as ``iterations + 1`` stages ``fn(state, i)`` with the angle
    one step ahead of the vector: stage i takes z through micro-rotation i (while i <
    iterations) and (x, y) through micro-rotation i - 1 (from stage 1), by the sign of z_(i-1)
    that stage i - 1 copied into ``cneg`` (for y) and ``cpos`` (for x).

    The same arithmetic as ``cordic_step(k, rotate=True)``, one stage later. Why: there, one
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


def atan2_coarse(k: Constants, add_sub, *, y: str, x: str):
    """The coarse stage of :func:`~ik5r.hdl.blocks.cordic.add_atan2` (``add_sub``: the datapath's adders)."""
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


def atan2_normalisation(k: Constants):
    """The three normalisation stages of :func:`~ik5r.hdl.blocks.cordic.add_atan2`."""
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


def add_magnitude(dp: Datapath, k: Constants, angle, keep_zero):
    """The magnitude stages of :func:`~ik5r.hdl.blocks.cordic.add_atan2`, the angle (``angle(state)``) and the zero
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
                 parallel=product_side, drop_keys=("cx", "cy", "cz", "cd", "czero"))
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
