"""The pipelined atan2's lean datapath (hdl/blocks/cordic_steps.py), the same integers in fewer
adder bits: (1) the angle tail: from the first micro-rotation whose step is an exact power of two,
the directions are kept and subtracted, doubled, at the end instead of one adder per step; (2) y
narrowed after each micro-rotation to its proven bound. The blocks' and cores' bit-exact runs
check both in hardware; here the premise (which steps are powers of two), the tail's identity on
the integers, and the bound against the model's y on random and extreme vectors."""

from __future__ import annotations

import random

import pytest

from ik5r.core.arm import load_arm
from ik5r.core.fixedpoint import rshift_round
from ik5r.core.fxconfig import constants, load_config
from ik5r.firmware_model.model import _bit_length_ones_abs
from ik5r.hdl.blocks.cordic_steps import angle_tail, tail_directions_weight, tail_offset, vectoring_y_widths

CONFIGS = ("q18", "q24", "q32", "q32w")


def _formats(name):
    k = constants(load_config(name), load_arm(None))
    return (k, k.internal) if k.internal is not k else (k,)


@pytest.mark.parametrize("name", CONFIGS)
def test_tail_starts_at_the_first_exact_power_of_two(name):
    for k in _formats(name):
        zf = k.cfg.frac_angle + k.cfg.angle_guard_bits
        tail, table = angle_tail(k), k.atan_table
        assert 1 <= tail < len(table), "every shipped config has a tail"
        assert all(table[i] == 1 << (zf - i) for i in range(tail, len(table)))
        assert table[tail - 1] != 1 << (zf - tail + 1)


@pytest.mark.parametrize("name", CONFIGS)
def test_kept_directions_give_the_accumulated_angle(name):
    """z after every step, rounded, equals (z_tail + offset - 2 * directions) >> guard for random
    accumulators and directions: the hardware's form of the same integer."""
    rng = random.Random(7)
    for k in _formats(name):
        c, tail, n = k.cfg, angle_tail(k), len(k.atan_table)
        for _ in range(2000):
            z_tail = rng.randrange(-k.half_pi_z - sum(k.atan_table), k.half_pi_z + sum(k.atan_table))
            down = [rng.random() < 0.5 for _ in range(tail, n)]
            z = z_tail
            for step, d in zip(k.atan_table[tail:], down):
                z = z - step if d else z + step
            bits = 0
            for d in down:                      # newest lowest, as the pipeline shifts them in
                bits = (bits << 1) | d
            kept = (z_tail + tail_offset(k) - (bits << (tail_directions_weight(k) + 1))) >> c.angle_guard_bits
            assert kept == rshift_round(z, c.angle_guard_bits, c.round_nearest)


def _y_after_each_step(k, y: int, x: int) -> list[int]:
    """y after each micro-rotation of ``model.cordic_atan2`` (its coarse step and normalisation)."""
    c = k.cfg
    if x < 0:
        x, y = (y, -x) if y >= 0 else (-y, x)
    norm = max(0, c.width - 1 - _bit_length_ones_abs(x, y))
    x, y = x << (norm + c.guard_bits), y << (norm + c.guard_bits)
    out = []
    for i in range(len(k.atan_table)):
        x, y = (x + (y >> i), y - (x >> i)) if y >= 0 else (x - (y >> i), y + (x >> i))
        out.append(y)
    return out


@pytest.mark.parametrize("name", ("q18", "q32w"))
def test_y_fits_its_narrowed_width(name):
    """Random vectors of every scale and the extremes: y after step i fits the proven width, and
    the widths are narrower than the register (or the change would be moot)."""
    rng = random.Random(11)
    for k in _formats(name):
        widths, top = vectoring_y_widths(k), 1 << (k.cfg.width - 1)
        assert sum(widths) < len(widths) * (k.cfg.width + k.cfg.guard_bits + 3) * 0.7
        vectors = [(top - 1, 0), (-top, 0), (top - 1, 1), (-top, -top), (top - 1, -top), (1, 0), (0, -1),
                   (-1, -top), (top - 1, top - 1)]
        vectors += [(rng.randrange(-top, top) >> rng.randrange(k.cfg.width),
                     rng.randrange(-top, top) >> rng.randrange(k.cfg.width)) for _ in range(3000)]
        for y, x in vectors:
            for i, value in enumerate(_y_after_each_step(k, y, x)):
                assert -(1 << (widths[i] - 1)) <= value < 1 << (widths[i] - 1), (y, x, i, value)
