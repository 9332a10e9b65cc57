"""The C solver (firmware_model/ik5r.c) against the scalar bit-accurate model (the specification).

Every comparison is exact: every joint word, every status bit, every building-block output.
Default run: ~3000 reachable poses x 4 branches x (with, without n/o) per config plus a directed
edge set, >= 20,000 random inputs per building block, a strict-warnings compile and an
ASan + UBSan build of the test driver run on the random and edge vectors. ``-m slow``: 1e6 poses
and 1e6 inputs per building block per config.
"""

from __future__ import annotations

import functools
import subprocess
from pathlib import Path

import numpy as np
import pytest

from ik5r.core import cbuild
from ik5r.core import status as st
from ik5r.core.fxconfig import constants, load_config
from ik5r.firmware_model import codegen, csolver, model
from ik5r.firmware_model.poses import PoseBatch, concat
from ik5r.firmware_model.vectors import edge_poses, random_poses

CONFIGS = ("q32", "q24", "q18", "q32w")
N_POSES = 3000
N_FUNC = 20000
N_SLOW = 1_000_000


@functools.lru_cache(maxsize=None)
def K(name):
    return constants(load_config(name))


@pytest.fixture(params=CONFIGS)
def name(request):
    return request.param


# ---------------------------------------------------------------------------------------------
# Vectors


def _special_words(k):
    lo, hi = k.word_min, k.word_max
    vals = {lo, lo + 1, lo + 2, -2, -1, 0, 1, 2, hi - 1, hi, k.one_u, -k.one_u, k.one_u - 1, 1 - k.one_u,
            k.one_u + 1, -k.one_u - 1, k.pi_a, -k.pi_a}
    for b in range(k.cfg.width - 1):
        vals |= {1 << b, -(1 << b), (1 << b) - 1, -(1 << b) + 1}
    return np.array(sorted(v for v in vals if lo <= v <= hi), dtype=np.int64)


def _random_words(k, rng, count):
    """Half uniform over the word range, half log-uniform magnitudes (small vectors, normalisation)."""
    half = count // 2
    uniform = rng.integers(k.word_min, k.word_max + 1, half)
    bits = rng.integers(0, k.cfg.width, count - half)
    mags = np.floor(rng.random(count - half) * (2.0 ** bits)).astype(np.int64)
    signed = np.where(rng.random(count - half) < 0.5, -mags, mags)
    return np.clip(np.concatenate([uniform, signed]), k.word_min, k.word_max)


def function_vectors(k, count, seed):
    """Inputs of each building block: random plus extremes (all pairs of special words)."""
    rng = np.random.default_rng(seed)
    s = _special_words(k)
    sy, sx = (g.ravel() for g in np.meshgrid(s, s))
    atan2 = (np.concatenate([_random_words(k, rng, count), sy]), np.concatenate([_random_words(k, rng, count), sx]))
    pi = k.pi_a
    angles = np.array([k.word_min, k.word_max, 0, 1, -1, pi, -pi, pi + 1, -pi - 1, pi + 7, -pi - 7, pi // 2,
                       -(pi // 2), pi // 2 + 1, -(pi // 2) - 1, pi // 4])
    ang_rand = np.where(rng.random(count) < 0.9, rng.integers(-pi - 16, pi + 17, count),
                        rng.integers(k.word_min, k.word_max + 1, count))
    gx, gy, ga = (g.ravel() for g in np.meshgrid(s[:: max(1, len(s) // 24)], s[:: max(1, len(s) // 24)], angles))
    rotate = (np.concatenate([_random_words(k, rng, count), gx]), np.concatenate([_random_words(k, rng, count), gy]),
              np.concatenate([ang_rand, ga]))
    near_one = np.concatenate([k.one_u + np.arange(-40, 41), -k.one_u + np.arange(-40, 41)])
    acos_in = np.concatenate([rng.integers(-k.one_u, k.one_u + 1, count - count // 4), _random_words(k, rng, count // 4),
                              near_one, s])
    acos_in = np.clip(acos_in, k.word_min, k.word_max)
    c = k.cfg
    fracs = np.array([c.frac_length, c.frac_unit, c.frac_angle, 0, 1, c.width - 2])
    sq_x = np.concatenate([np.abs(_random_words(k, rng, count - count // 8)), _random_words(k, rng, count // 8),
                           np.repeat(s, len(fracs))])
    sq_x = np.clip(sq_x, k.word_min, k.word_max)
    sq_f = np.concatenate([rng.choice(fracs, count), np.tile(fracs, len(s))])
    bits = rng.choice(np.arange(0, 65, 2), count)
    top = np.minimum(bits, 63)
    rad = (rng.random(count) * 2.0 ** top).astype(np.uint64) | (rng.integers(0, 1 << 20, count).astype(np.uint64))
    rad = np.where(bits == 64, rng.integers(0, 2**63, count, dtype=np.uint64) * np.uint64(2)
                   + rng.integers(0, 2, count, dtype=np.uint64), rad)
    edge_rad = np.array([0, 1, 2, 3, 2**62, 2**63, 2**64 - 1, 2**63 - 1, 2**62 - 1, (2**32 - 1) ** 2,
                         (2**32 - 1) ** 2 + 2**32 - 1, (2**32 - 1) ** 2 + 2**32], dtype=np.uint64)
    isq = (np.concatenate([rad, edge_rad, edge_rad]), np.concatenate([bits, np.full(24, 64)]),
           rng.random(count + 24) < 0.5)
    return {"atan2": atan2, "rotate": rotate, "acos": (acos_in,), "sqrt_word": (sq_x, sq_f), "isqrt64": isq}


# ---------------------------------------------------------------------------------------------
# Model side (scalar spec; cached per config)


def model_function(k, fn, inputs):
    """The scalar model's outputs for one building block as a tuple of int64 (or object) arrays."""
    if fn == "atan2":
        out = [model.cordic_atan2(int(y), int(x), k) for y, x in zip(*inputs)]
    elif fn == "rotate":
        out = [model.cordic_rotate(int(x), int(y), int(a), k) for x, y, a in zip(*inputs)]
    elif fn == "acos":
        out = [model.cordic_acos(int(x), k) for x in inputs[0]]
    elif fn == "sqrt_word":
        out = [(model.sqrt_word(int(x), int(f), k),) for x, f in zip(*inputs)]
    elif fn == "isqrt64":
        out = [(model.isqrt(int(r), int(b), bool(n)),) for r, b, n in zip(*inputs)]
    else:
        raise ValueError(fn)
    return tuple(np.array([int(v) for v in col], dtype=object) for col in zip(*out))


def c_function(cs, fn, inputs):
    if fn in ("isqrt64", "sqrt_word"):
        return (getattr(cs, fn)(*inputs),)
    return getattr(cs, fn)(*inputs)


def assert_same(c_out, m_out, what, inputs=None):
    for i, (cv, mv) in enumerate(zip(c_out, m_out)):
        cv = np.array([int(v) for v in cv], dtype=object)
        bad = np.flatnonzero(cv != mv)
        if bad.size:
            j = bad[0]
            where = "" if inputs is None else f" input {[int(col[j]) for col in inputs]}"
            pytest.fail(f"{what}: output {i} differs on {bad.size} of {len(cv)};{where}: C {cv[j]} model {mv[j]}")


@functools.lru_cache(maxsize=None)
def random_case(name):
    k = K(name)
    poses = random_poses(k, N_POSES, seed=1234 + CONFIGS.index(name))
    return poses, model.solve_batch(k, *poses.args())


@functools.lru_cache(maxsize=None)
def edge_case(name):
    k = K(name)
    poses = edge_poses(k)
    return poses, model.solve_batch(k, *poses.args())


@functools.lru_cache(maxsize=None)
def function_case(name):
    k = K(name)
    vectors = function_vectors(k, N_FUNC, seed=99 + CONFIGS.index(name))
    return vectors, {fn: model_function(k, fn, inp) for fn, inp in vectors.items()}


def assert_poses_equal(poses, c_result, m_result, what):
    q_c, st_c = c_result
    q_m, st_m = m_result
    bad = np.flatnonzero((q_c != q_m).any(axis=1) | (st_c != st_m))
    if bad.size:
        i = bad[0]
        pytest.fail(f"{what}: {bad.size} of {len(poses)} poses differ; first row {i}: "
                    f"p {poses.p[i]} a {poses.a[i]} n {poses.n[i]} o {poses.o[i]} roll {poses.roll[i]} "
                    f"back {poses.back[i]} down {poses.down[i]} q5 {poses.q5[i]}: "
                    f"C {q_c[i]} status {st_c[i]}, model {q_m[i]} status {st_m[i]}")


# ---------------------------------------------------------------------------------------------
# Tests


def test_header_generated_deterministic(name, tmp_path):
    k = K(name)
    text = codegen.generate_header(k)
    assert text == codegen.generate_header(constants(load_config(name)))
    assert f'"{name}" ({name}.toml)' in text and "GENERATED" in text
    assert str(Path(k.cfg.source).parent) not in text and str(k.cfg.source) not in text
    for value in k.atan_table:
        assert f"INT64_C({value})" in text
    for field in ("width", "frac_length", "frac_unit", "frac_angle", "iterations", "guard_bits",
                  "angle_guard_bits", "internal_guard_bits"):
        assert f"#define IK5R_{field.upper()} {getattr(k.cfg, field)}\n" in text
    # The internal format of the IK (the word format when internal_guard_bits is 0).
    inner = k.internal.cfg
    assert f"#define IK5R_IK_WIDTH {k.cfg.width + k.cfg.internal_guard_bits}\n" in text
    assert f"#define IK5R_IK_ITERATIONS {inner.iterations}\n" in text
    for value in k.internal.atan_table:
        assert f"INT64_C({value})" in text
    twice = int(k.internal.twice_a2a3_l2)
    assert f"#define IK5R_IK_TWICE_A2A3_L2_HI UINT64_C({twice >> 64})\n" in text
    assert f"#define IK5R_IK_TWICE_A2A3_L2_LO UINT64_C({twice & (2**64 - 1)})\n" in text
    assert f"#define IK5R_ROUND_NEAREST {int(k.cfg.round_nearest)}\n" in text
    assert f"#define IK5R_C3_FROM_L2_MANT INT64_C({k.c3_from_l2.mant})" in text
    assert "#define IK5R_STATUS_SINGULAR_BASE 0x04u" in text


def test_header_not_in_source_tree(name):
    csolver.CSolver(K(name))
    assert not (csolver.SOURCE_DIR / codegen.HEADER_NAME).exists()
    assert csolver.SOURCE_DIR not in csolver.build_library(K(name)).parents


def test_solve_random_matches_model(name):
    poses, expected = random_case(name)
    cs = csolver.solver(K(name))
    assert_poses_equal(poses, cs.solve_batch(*poses.args()), expected, f"{name} random")
    # The module-level wrapper has the model's signature.
    assert_poses_equal(poses, csolver.solve_batch(K(name), *poses.args()), expected, f"{name} random")


def test_solve_edges_match_model(name):
    poses, expected = edge_case(name)
    cs = csolver.solver(K(name))
    assert_poses_equal(poses, cs.solve_batch(*poses.args()), expected, f"{name} edges")
    # The edge set exercises every status bit the fixed-point IK can set.
    seen = np.bitwise_or.reduce(expected[1])
    assert seen == st.FIXED_BITS, bin(seen)


@pytest.mark.parametrize("fn", ["atan2", "rotate", "acos", "sqrt_word", "isqrt64"])
def test_function_matches_model(name, fn):
    vectors, expected = function_case(name)
    cs = csolver.solver(K(name))
    assert len(vectors[fn][0]) >= N_FUNC
    assert_same(c_function(cs, fn, vectors[fn]), expected[fn], f"{name} {fn}", vectors[fn])


def test_strict_warnings(name):
    result = csolver.warnings_check(K(name))
    assert result.returncode == 0 and not result.stderr, result.stderr


def _driver_function_lines(fn, inputs, limit):
    tag = {"atan2": "A", "rotate": "R", "acos": "C", "sqrt_word": "Q", "isqrt64": "I"}[fn]
    cols = [np.asarray(c)[:limit] for c in inputs]
    if fn == "isqrt64":
        cols[2] = cols[2].astype(int)
    return [tag + " " + " ".join(str(int(v)) for v in row) for row in zip(*cols)]


def test_sanitizer_driver(name):
    k = K(name)
    driver = csolver.build_test_driver(k, sanitize=True)
    random_poses_, random_expected = random_case(name)
    edges, edge_expected = edge_case(name)
    vectors, fexpected = function_case(name)
    lines = random_poses_.driver_lines() + edges.driver_lines()
    limit = 5000
    for fn, inputs in vectors.items():
        lines += _driver_function_lines(fn, inputs, limit)
    out = csolver.run_test_driver(driver, lines)
    assert len(out) == len(lines)
    rows = np.array([list(map(int, line.split())) for line in out[:len(random_poses_) + len(edges)]], dtype=np.int64)
    q = np.concatenate([random_expected[0], edge_expected[0]])
    st = np.concatenate([random_expected[1], edge_expected[1]])
    both = concat(random_poses_, edges)
    assert_poses_equal(both, (rows[:, :5], rows[:, 5]), (q, st), f"{name} sanitizer driver")
    pos = len(random_poses_) + len(edges)
    for fn, inputs in vectors.items():
        count = min(limit, len(inputs[0]))
        got = [line.split() for line in out[pos:pos + count]]
        pos += count
        c_out = tuple(np.array([int(r[i]) for r in got], dtype=object) for i in range(len(got[0])))
        if fn == "atan2":
            c_out = (c_out[0], c_out[1], c_out[2].astype(bool))
        m_out = tuple(col[:count] for col in fexpected[fn])
        assert_same(c_out, m_out, f"{name} driver {fn}", [c[:count] for c in inputs])


def test_sanitizer_catches_ub(tmp_path):
    """The sanitizer flags really abort on UB (guards against a silently inert build)."""
    src = tmp_path / "ub.c"
    src.write_text("#include <stdint.h>\n#include <stdlib.h>\nint main(int c, char **v) {\n"
                   "  int64_t x = INT64_MAX - 1 + (int64_t)atoi(v[c - 1]);\n  return (int)((x + 5) & 1);\n}\n")
    exe = tmp_path / "ub"
    subprocess.run([cbuild.compiler(), *cbuild.SANITIZE_FLAGS, str(src), "-o", str(exe)], check=True)
    result = subprocess.run([str(exe), "3"], capture_output=True, text=True)
    assert result.returncode != 0 and "overflow" in result.stderr


def test_c_rejects_non_words():
    cs = csolver.solver(K("q18"))
    with pytest.raises(ValueError):
        cs.atan2([1 << 17], [0])
    z = np.zeros((1, 3), np.int64)
    with pytest.raises(ValueError):
        cs.solve_batch(z + (1 << 17), z, z, z, [False], [False], [False], [0])


# ---------------------------------------------------------------------------------------------
# Slow: 1e6 vectors per config (vectorised model if present, else the scalar model in chunks)


def _vector_model():
    try:
        from ik5r.firmware_model import vector
    except ImportError:
        return None
    return vector


def _reference_solve(k, poses):
    """Model results for many poses: the vectorised model where it agrees with the scalar spec."""
    vector = _vector_model()
    if vector is None:
        return model.solve_batch(k, *poses.args())
    return vector.solve_batch(k, *poses.args())


@pytest.mark.slow
def test_slow_million_poses(name):
    k = K(name)
    cs = csolver.solver(k)
    count = N_SLOW // 8
    poses = random_poses(k, count, seed=2024 + CONFIGS.index(name))
    # Mix in raw random words (unreachable, saturating) for a sixth of the rows.
    rng = np.random.default_rng(5)
    m = len(poses) // 6
    poses.p[:m] = rng.integers(k.word_min, k.word_max + 1, (m, 3))
    poses.a[:m] = rng.integers(k.word_min, k.word_max + 1, (m, 3))
    got = cs.solve_batch(*poses.args())
    expected = _reference_solve(k, poses)
    bad = np.flatnonzero((got[0] != expected[0]).any(axis=1) | (got[1] != expected[1]))
    if bad.size:
        # Settle every disagreement against the scalar specification.
        sub = poses[bad]
        spec = model.solve_batch(k, *sub.args())
        assert_poses_equal(sub, (got[0][bad], got[1][bad]), spec, f"{name} slow poses (C vs scalar spec)")
        pytest.fail(f"vectorised model disagrees with the scalar model on {bad.size} poses (C is right)")


@pytest.mark.slow
@pytest.mark.parametrize("fn", ["atan2", "rotate", "acos", "sqrt_word", "isqrt64"])
def test_slow_million_function(name, fn):
    k = K(name)
    cs = csolver.solver(k)
    vectors = function_vectors(k, N_SLOW, seed=4242 + CONFIGS.index(name))[fn]
    got = c_function(cs, fn, vectors)
    vector = _vector_model()
    if vector is not None and fn != "isqrt64":
        vfn = {"atan2": lambda y, x: vector.cordic_atan2(y, x, k), "rotate": lambda x, y, a: vector.cordic_rotate(x, y, a, k),
               "acos": lambda x: vector.cordic_acos(x, k)}.get(fn)
        if vfn is not None:
            expected = tuple(np.asarray(v).astype(np.int64) for v in vfn(*vectors))
            bad = np.zeros(len(vectors[0]), bool)
            for g, e in zip(got, expected):
                bad |= np.asarray(g).astype(np.int64) != e
            idx = np.flatnonzero(bad)
            if idx.size == 0:
                return
            sub = tuple(np.asarray(v)[idx] for v in vectors)
            assert_same(tuple(np.asarray(g)[idx] for g in got), model_function(k, fn, sub), f"{name} slow {fn}", sub)
            pytest.fail(f"vectorised model disagrees with the scalar model on {idx.size} {fn} inputs (C is right)")
    # Scalar model in chunks.
    for start in range(0, len(vectors[0]), 100_000):
        sub = tuple(np.asarray(v)[start:start + 100_000] for v in vectors)
        assert_same(tuple(np.asarray(g)[start:start + 100_000] for g in got), model_function(k, fn, sub),
                    f"{name} slow {fn}", sub)


@pytest.mark.slow
def test_slow_sanitizer_driver_random_words(name):
    """200,000 raw random-word poses (every input full range) through the ASan/UBSan driver."""
    k = K(name)
    rng = np.random.default_rng(77 + CONFIGS.index(name))
    count = 200_000
    w = lambda *shape: rng.integers(k.word_min, k.word_max + 1, shape)  # noqa: E731
    poses = PoseBatch(w(count, 3), w(count, 3), w(count, 3), w(count, 3), rng.random(count) < 0.5,
                  rng.random(count) < 0.5, rng.random(count) < 0.5, w(count))
    out = csolver.run_test_driver(csolver.build_test_driver(k), poses.driver_lines(), timeout=1800)
    rows = np.array([list(map(int, line.split())) for line in out], dtype=np.int64)
    assert_poses_equal(poses, (rows[:, :5], rows[:, 5]), _reference_solve(k, poses), f"{name} slow driver")

