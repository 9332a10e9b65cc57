"""The pipelined atan2's angle tail (hdl/blocks/cordic_steps.py): from the first micro-rotation
whose step is an exact power of two, the directions are kept and subtracted, doubled, at the end
instead of one adder per step. The blocks' and cores' bit-exact runs check it in hardware; here
the premise (which steps are powers of two) and the identity itself, on the integers."""

from __future__ import annotations

import random

import pytest

from ik5r.core.arm import load_arm
from ik5r.core.fixedpoint import rshift_round
from ik5r.core.fxconfig import constants, load_config
from ik5r.hdl.blocks.cordic_steps import angle_tail, tail_directions_weight, tail_offset

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
