"""The vectorised model (firmware_model/vector.py) against the scalar specification (model.py).

Every comparison is exact: every bit of every output word and every status bit.
The default run covers >= 5000 random reachable poses x 4 branches per config, a directed edge set,
>= 100,000 random inputs per CORDIC / square-root function per config and the exhaustive q18 acos
and sqrt_word; ``-m slow`` adds 1,000,000 poses and 1,000,000 inputs per function per config.
"""

from __future__ import annotations

import itertools
import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace

import numpy as np
import pytest

from ik5r.core.arm import load_arm
from ik5r.core.fxconfig import Constants, constants, load_config
from ik5r.core.status import INVALID, SATURATED, SINGULAR_BASE, SINGULAR_ELBOW, UNREACHABLE
from ik5r.firmware_model import model, vector
from ik5r.firmware_model.poses import PoseBatch
from ik5r.firmware_model.vectors import edge_poses, random_poses

CONFIGS = ("q18", "q24", "q32", "q32w")
ARM = load_arm()


def _constants(name: str) -> Constants:
    if name.endswith("-truncate"):
        cfg = load_config(name.removesuffix("-truncate"))
        return Constants(replace(cfg, rounding="truncate"), ARM)
    return constants(load_config(name), ARM)


@pytest.fixture(scope="module", params=CONFIGS)
def k(request) -> Constants:
    return _constants(request.param)


# ----------------------------------------------------------------------------------------------
# Input generators


def _words(k: Constants, rng, count: int) -> np.ndarray:
    """Random words: half uniform over the whole range, half drawn from the awkward ones
    (extremes, +-1 unit, tiny values, powers of two and their neighbours)."""
    w = k.cfg.width
    pows = [s * ((1 << j) + d) for j in range(w - 1) for d in (-1, 0, 1) for s in (1, -1)]
    special = np.array(sorted({k.word_min, k.word_min + 1, k.word_max, k.word_max - 1, 0, 1, -1,
                               k.one_u, -k.one_u, k.one_u + 1, -k.one_u - 1, k.one_u - 1, 1 - k.one_u,
                               *range(-8, 9), *pows}), dtype=np.int64)
    special = special[(special >= k.word_min) & (special <= k.word_max)]
    uniform = rng.integers(k.word_min, k.word_max + 1, count)
    picked = special[rng.integers(0, len(special), count)]
    small = rng.integers(-64, 65, count)
    choice = rng.integers(0, 4, count)
    return np.select([choice == 0, choice == 1, choice == 2], [uniform, picked, small], uniform)


def _angles(k: Constants, rng, count: int) -> np.ndarray:
    """Angles of the nominal range |a| <= pi + a few LSB, the quadrant boundaries and any word."""
    edge = k.half_pi_z >> k.cfg.angle_guard_bits
    special = np.array([0, 1, -1, k.pi_a, -k.pi_a, k.pi_a + 1, -k.pi_a - 1, edge, edge + 1, -edge,
                        -edge - 1, edge - 1, 1 - edge, k.word_max, k.word_min], dtype=np.int64)
    nominal = rng.integers(-k.pi_a - 16, k.pi_a + 17, count)
    choice = rng.integers(0, 8, count)
    return np.select([choice == 0, choice == 1], [special[rng.integers(0, len(special), count)],
                                                   _words(k, rng, count)], nominal)


def _scalar(fn, *columns):
    """The scalar function over columns of ints: a list of its results (tuples or ints)."""
    return [fn(*(int(v) for v in row)) for row in zip(*columns)]


def _assert_equal(name, got: np.ndarray, want, inputs) -> None:
    want = np.array(want, dtype=object)
    got = np.asarray(got)
    assert got.shape == want.shape, (name, got.shape, want.shape)
    bad = np.flatnonzero(got.astype(object) != want)
    if bad.size:
        i = bad[0]
        raise AssertionError(f"{name}: {bad.size} of {want.size} differ; first at {i}: inputs "
                             f"{[int(c[i]) for c in inputs]}, vector {got[i]}, scalar {want[i]}")


# ----------------------------------------------------------------------------------------------
# Per-function checks


def _check_atan2(k, y, x):
    want = _scalar(lambda a, b: model.cordic_atan2(a, b, k), y, x)
    angle, magnitude, zero = vector.cordic_atan2(y, x, k)
    _assert_equal("atan2.angle", angle, [w[0] for w in want], (y, x))
    _assert_equal("atan2.magnitude", magnitude, [w[1] for w in want], (y, x))
    _assert_equal("atan2.zero", zero, [w[2] for w in want], (y, x))


def _check_rotate(k, x, y, angle):
    want = _scalar(lambda a, b, c: model.cordic_rotate(a, b, c, k), x, y, angle)
    got = vector.cordic_rotate(x, y, angle, k)
    for j, part in enumerate(("x", "y", "sat")):
        _assert_equal(f"rotate.{part}", got[j], [w[j] for w in want], (x, y, angle))


def _check_acos(k, x):
    want = _scalar(lambda a: model.cordic_acos(a, k), x)
    got = vector.cordic_acos(x, k)
    for j, part in enumerate(("angle", "sine", "flags")):
        _assert_equal(f"acos.{part}", got[j], [w[j] for w in want], (x,))


def _check_sqrt_word(k, x, frac):
    want = _scalar(lambda a: model.sqrt_word(a, frac, k), x)
    _assert_equal(f"sqrt_word(frac={frac})", vector.sqrt_word(x, frac, k), want, (x,))


def _radicands(rng, bits: int, count: int) -> np.ndarray:
    """uint64 radicands below 2**bits: uniform, uniform in bit length, and at the rounding
    boundaries r^2 - 1, r^2, r^2 + r, r^2 + r + 1 (and the extremes)."""
    top = (1 << bits) - 1
    uniform = rng.integers(0, top, count, dtype=np.uint64, endpoint=True)
    lengths = rng.integers(0, bits + 1, count).astype(np.uint64)
    by_length = uniform >> (np.uint64(bits) - lengths)
    r = rng.integers(0, 1 << (bits // 2), count, dtype=np.uint64)
    offset = rng.integers(0, 4, count)
    boundary = np.select([offset == 0, offset == 1, offset == 2],
                         [r * r - np.uint64(1), r * r, r * r + r], r * r + r + np.uint64(1))
    boundary = np.where(boundary > np.uint64(top), np.uint64(top), boundary)  # r^2 + r + 1 wraps
    out = np.select([np.arange(count) % 3 == 0, np.arange(count) % 3 == 1], [uniform, by_length], boundary)
    extremes = np.array([0, 1, 2, 3, 4, top, top - 1, top >> 1, (top >> 1) + 1], dtype=np.uint64)
    out[:len(extremes)] = extremes
    return out


def _check_isqrt(rng, count: int, nearest: bool):
    for bits in (64, 62, 60, 48, 36, 34, 20, 2):
        rad = _radicands(rng, bits, count)
        want = [model.isqrt(int(v), bits, nearest) for v in rad]
        _assert_equal(f"isqrt({bits}, nearest={nearest})", vector.isqrt(rad, bits, nearest), want, (rad,))


def _function_inputs(k, rng, count):
    return dict(y=_words(k, rng, count), x=_words(k, rng, count), angle=_angles(k, rng, count),
                acos=np.concatenate([_words(k, rng, count // 2),
                                     rng.integers(-k.one_u - 64, k.one_u + 65, count - count // 2)]),
                sqrt=np.abs(_words(k, rng, count)).clip(0, k.word_max))


def _check_functions(k, rng, count):
    inputs = _function_inputs(k, rng, count)
    _check_atan2(k, inputs["y"], inputs["x"])
    _check_rotate(k, inputs["x"], inputs["y"], inputs["angle"])
    _check_acos(k, inputs["acos"])
    _check_sqrt_word(k, inputs["sqrt"], k.cfg.frac_unit)


def test_atan2(k):
    rng = np.random.default_rng(101)
    y, x = _words(k, rng, 100_000), _words(k, rng, 100_000)
    # Every pairing of the awkward values (both signs, zero, axes, diagonals, extremes).
    edge = np.array([0, 1, -1, k.word_max, k.word_min, k.word_min + 1, k.one_u, -k.one_u, 3, -3])
    ey, ex = (np.array(v) for v in zip(*itertools.product(edge, repeat=2)))
    _check_atan2(k, np.concatenate([y, ey]), np.concatenate([x, ex]))


def test_rotate(k):
    rng = np.random.default_rng(102)
    x, y, angle = _words(k, rng, 100_000), _words(k, rng, 100_000), _angles(k, rng, 100_000)
    edge = np.array([0, 1, -1, k.word_max, k.word_min, k.one_u, -k.one_u])
    ex, ey = (np.array(v) for v in zip(*itertools.product(edge, repeat=2)))
    for a in (0, k.pi_a, -k.pi_a, k.half_pi_z >> k.cfg.angle_guard_bits, k.word_min, k.word_max):
        x, y, angle = (np.concatenate([x, ex]), np.concatenate([y, ey]),
                       np.concatenate([angle, np.full(len(ex), a)]))
    _check_rotate(k, x, y, angle)


def test_acos(k):
    rng = np.random.default_rng(103)
    x = _function_inputs(k, rng, 100_000)["acos"]
    _check_acos(k, np.concatenate([x, [0, 1, -1, k.one_u, -k.one_u, k.word_max, k.word_min]]))


def test_sqrt_word(k):
    rng = np.random.default_rng(104)
    x = np.concatenate([_function_inputs(k, rng, 100_000)["sqrt"], [0, 1, 2, 3, 4, k.word_max]])
    for frac in (k.cfg.frac_unit, k.cfg.frac_length, k.cfg.frac_angle, 0, 1):
        _check_sqrt_word(k, x if frac == k.cfg.frac_unit else x[:20_000], frac)


def test_isqrt():
    rng = np.random.default_rng(105)
    _check_isqrt(rng, 100_000, nearest=True)
    _check_isqrt(rng, 20_000, nearest=False)


def test_isqrt_two_complement():
    """The vector isqrt reads the low bits of int64 radicands like the scalar model, negatives too."""
    rng = np.random.default_rng(106)
    rad = rng.integers(np.iinfo(np.int64).min, np.iinfo(np.int64).max, 20_000, endpoint=True)
    for bits in (64, 40):
        want = [model.isqrt(int(v), bits, True) for v in rad]
        _assert_equal(f"isqrt int64 ({bits})", vector.isqrt(rad, bits, True), want, (rad,))


def test_bit_length():
    rng = np.random.default_rng(107)
    v = np.concatenate([rng.integers(0, 2**63 - 1, 50_000, endpoint=True) >> rng.integers(0, 63, 50_000),
                        [0, 1, 2, 3, 2**62, 2**63 - 1], [(1 << j) + d for j in range(1, 62) for d in (-1, 0, 1)]])
    want = [int(x).bit_length() for x in v]
    _assert_equal("bit_length", vector.bit_length(v), want, (v,))                 # binary search
    _assert_equal("bit_length search", vector._bit_length_search(v), want, (v,))
    small = v[v < 2**53]                                                           # float path
    _assert_equal("bit_length < 2**53", vector.bit_length(small), [int(x).bit_length() for x in small], (small,))
    top = np.array([2**53 - 1, 2**53 - 2, 2**52, 2**52 - 1, 2**52 + 1, 2**33, 2**32 - 1, 0])
    _assert_equal("bit_length top", vector.bit_length(top), [int(x).bit_length() for x in top], (top,))


def test_helpers(k):
    rng = np.random.default_rng(108)
    v = _words(k, rng, 20_000)
    wide = v * 8 + rng.integers(-7, 8, len(v))
    for nearest in (True, False):
        for shift in (-3, 0, 1, 5):
            want = [model.rshift_round(int(a), shift, nearest) for a in wide]
            _assert_equal("rshift_round", vector.rshift_round(wide, shift, nearest), want, (wide,))
        shifts = rng.integers(-3, 40, len(v))
        want = [model.rshift_round(int(a), int(s), nearest) for a, s in zip(wide, shifts)]
        _assert_equal("rshift_round(array)", vector.rshift_round(wide, shifts, nearest), want, (wide, shifts))
    got, flags = vector.saturate(wide, k)
    want = [model.saturate(int(a), k) for a in wide]
    _assert_equal("saturate", got, [w[0] for w in want], (wide,))
    _assert_equal("saturate.flags", flags, [w[1] for w in want], (wide,))
    for m in (k.c3_from_l2, k.a3_from_u):
        x = rng.integers(-(1 << (30 + m.pre)), 1 << (30 + m.pre), 20_000)
        want = [model.mul_const(int(a), m, k.cfg.round_nearest) for a in x]
        _assert_equal("mul_const", vector.mul_const(x, m, k.cfg.round_nearest), want, (x,))
    a = np.concatenate([_angles(k, rng, 20_000), [k.pi_a, -k.pi_a, 0]])
    a2 = np.concatenate([a, a + k.pi_a, a - k.pi_a])
    _assert_equal("wrap_angle", vector.wrap_angle(a2, k), [model.wrap_angle(int(x), k) for x in a2], (a2,))
    _assert_equal("opposite", vector.opposite(a, k), [model.opposite(int(x), k) for x in a], (a,))


# Exhaustive over every q18 word: 2**18 inputs each.

def test_acos_exhaustive_q18():
    k = _constants("q18")
    _check_acos(k, np.arange(k.word_min, k.word_max + 1, dtype=np.int64))


def test_sqrt_word_exhaustive_q18():
    k = _constants("q18")
    x = np.arange(k.word_min, k.word_max + 1, dtype=np.int64)   # negatives too: read as the model does
    for frac in (k.cfg.frac_unit, k.cfg.frac_length):
        _check_sqrt_word(k, x, frac)


# ----------------------------------------------------------------------------------------------
# Poses


def _compare_poses(k, poses: PoseBatch) -> np.ndarray:
    """vector == model on every pose row (branch, roll and q5 per row); returns the statuses."""
    q_s, st_s = model.solve_batch(k, *poses.args())
    q_v, st_v = vector.solve_batch(k, *poses.args())
    assert q_v.dtype == np.int64 and st_v.dtype == np.int64
    assert q_v.shape == (len(poses), 5) and st_v.shape == (len(poses),)
    bad = np.flatnonzero((q_s != q_v).any(axis=1) | (st_s != st_v))
    if bad.size:
        i = bad[0]
        raise AssertionError(
            f"{bad.size} of {len(poses)} poses differ; first {i}: p={poses.p[i]} a={poses.a[i]} "
            f"n={poses.n[i]} o={poses.o[i]} roll={poses.roll[i]} back={poses.back[i]} down={poses.down[i]} "
            f"q5={poses.q5[i]}: vector {q_v[i]} {st_v[i]}, model {q_s[i]} {st_s[i]}")
    return st_s


@pytest.mark.parametrize("name", CONFIGS + ("q32-truncate", "q32w-truncate"))
def test_random_poses(name):
    k = _constants(name)
    status = _compare_poses(k, random_poses(k, 1250, seed=201))
    assert np.mean(status == 0) > 0.3   # the bulk of reachable poses solve cleanly


def test_edge_poses(k):
    poses = edge_poses(k)
    # Cross the q5 input with its extremes too.
    q5_values = np.array([0, k.pi_a, -k.pi_a, k.word_min, k.word_max])
    rows = np.arange(len(poses)).repeat(len(q5_values))
    crossed = PoseBatch(*(v[rows] for v in poses.args()[:-1]), np.tile(q5_values, len(poses)))
    status = _compare_poses(k, crossed)
    # The edge set does reach the flags it is meant to.
    for bit in (UNREACHABLE, SINGULAR_ELBOW, SINGULAR_BASE, SATURATED, INVALID):
        assert (status & bit).any(), bit


def test_solve_batch_interface(k):
    """n_u / o_u rows without roll are not read; words are required; empty batches work."""
    rng = np.random.default_rng(301)
    p, a, n, o, roll, _, _, q5 = random_poses(k, 50, seed=301).args()
    roll = np.zeros(len(p), dtype=bool)
    back = down = np.zeros(len(p), dtype=bool)
    ref_q, ref_st = vector.solve_batch(k, p, a, n, o, roll, back, down, q5)
    garbage = rng.integers(k.word_min, k.word_max + 1, (len(p), 3))
    got_q, got_st = vector.solve_batch(k, p, a, garbage, garbage, roll, back, down, q5)
    assert (got_q == ref_q).all() and (got_st == ref_st).all()
    got_q, got_st = vector.solve_batch(k, p, a, None, None, roll, back, down, q5)
    assert (got_q == ref_q).all() and (got_st == ref_st).all()
    with pytest.raises(ValueError):
        vector.solve_batch(k, p + (k.word_max + 1), a, n, o, roll, back, down, q5)
    with pytest.raises(ValueError):
        vector.solve_batch(k, p, a, None, None, ~roll, back, down, q5)
    empty = np.zeros((0, 3), dtype=np.int64)
    q_e, st_e = vector.solve_batch(k, empty, empty, empty, empty, [], [], [], [])
    assert q_e.shape == (0, 5) and st_e.shape == (0,)


def test_chunk_boundaries(k, monkeypatch):
    args = random_poses(k, 125, seed=302).args()
    full = vector.solve_batch(k, *args)
    monkeypatch.setattr(vector, "CHUNK", 77)
    chunked = vector.solve_batch(k, *args)
    assert (full[0] == chunked[0]).all() and (full[1] == chunked[1]).all()


# ----------------------------------------------------------------------------------------------
# Slow: 1,000,000 poses and 1,000,000 inputs per function per config.


def _scalar_poses(args):
    name, seed, count = args
    k = _constants(name)
    # random_poses gives every pose in 8 variants (4 branches x with/without n, o).
    args = random_poses(k, count // 8, seed=seed).args()
    q_s, st_s = model.solve_batch(k, *args)
    q_v, st_v = vector.solve_batch(k, *args)
    return int(((q_s != q_v).any(axis=1) | (st_s != st_v)).sum())


def _scalar_functions(args):
    name, seed, count = args
    k = _constants(name)
    _check_functions(k, np.random.default_rng(seed), count)
    _check_isqrt(np.random.default_rng(seed + 1), count // 8, nearest=True)   # 8 widths
    return 0


def _in_parallel(fn, name, total, piece=50_000):
    jobs = [(name, 1000 + i, min(piece, total - start)) for i, start in enumerate(range(0, total, piece))]
    with ProcessPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
        return sum(pool.map(fn, jobs))


@pytest.mark.slow
@pytest.mark.parametrize("name", CONFIGS)
def test_million_poses(name):
    assert _in_parallel(_scalar_poses, name, 1_000_000) == 0


@pytest.mark.slow
@pytest.mark.parametrize("name", CONFIGS)
def test_million_per_function(name):
    assert _in_parallel(_scalar_functions, name, 1_000_000) == 0
