"""The C LM kernel (ik5r.numeric.lmkernel, csrc/lm_kernel.c) against the numpy reference
(ik5r.numeric.solver.levenberg_marquardt), its strict-warning build and its sanitizer build."""

from __future__ import annotations

import ctypes
import subprocess
import tomllib

import numpy as np
import pytest
from test_numeric import PRISMATIC_ARM

from ik5r.core import cbuild
from ik5r.core.chain import fk, jacobian, load_chain, parse_chain, random_joints, shipped_arm
from ik5r.firmware_model import csolver
from ik5r.numeric import lmkernel, multistart
from ik5r.numeric import solver as nm

#: A 7R arm (more joints than task rows: the kernel's J J^T branch), tool offset, reversed joint.
SEVEN_R = {"joint": [{"a": 0, "alpha": 90, "d": 30}, {"a": 40, "alpha": 0}, {"a": 5, "alpha": -90, "d": 10},
                     {"a": 0, "alpha": 90, "d": 35, "scale": -1}, {"a": 0, "alpha": -90},
                     {"a": 0, "alpha": 90, "d": 5}, {"a": 0, "alpha": 0, "d": 8, "limits": [-90, 120]}],
           "tool": {"xyz": [1, 2, 10], "rpy": [5, -10, 15]}}


def _case(name):
    """(chain, mode) of every kernel branch: standard/modified DH, revolute/prismatic/wrapped,
    scale -1, tool, n < 6, n = 6, n > 6, pose/position/direction."""
    if name == "prismatic":
        return parse_chain(tomllib.loads(PRISMATIC_ARM), "prismatic.toml"), "position"
    if name == "seven-r":
        return parse_chain(SEVEN_R, "seven-r.toml"), "pose"
    arm, mode = name.split(":")
    return load_chain(shipped_arm(arm)), mode


CASES = ("puma560:pose", "toz-6r:pose", "park-5r:direction", "hu-5r:position", "prismatic", "seven-r")


def _problem(name, count, seed, hard=False):
    """(chain, targets, starts); ``hard``: the first starts take the lanes' fallbacks (_hard_starts)."""
    chain, mode = _case(name)
    rng = np.random.default_rng(seed)
    q_target = random_joints(chain, count, rng)
    R, p = fk(chain, q_target)
    targets = nm.Targets(mode, p, R if mode == "pose" else None, R[:, :, 2] if mode == "direction" else None)
    q0 = random_joints(chain, count, rng)
    return chain, targets, _hard_starts(chain, q_target, q0) if hard else q0


@pytest.mark.parametrize("name", CASES)
@pytest.mark.parametrize("polish", [True, False])
def test_c_kernel_agrees_with_numpy(name, polish):
    chain, targets, q0 = _problem(name, 300, 1)
    ref = nm.levenberg_marquardt(chain, targets, q0, polish=polish)
    got = lmkernel.levenberg_marquardt(chain, targets, q0, polish=polish)
    assert (got[3] == ref[3]).all()  # converged: same rows
    assert (got[4] == ref[4]).all()  # singular: same rows
    assert ref[3].mean() > 0.3  # the comparison covers converged rows
    conv = ref[3]
    wraps = chain.wraps()
    diff = np.abs(got[0] - ref[0])
    diff[:, wraps] = np.minimum(diff[:, wraps], 2 * np.pi - diff[:, wraps])
    rows = 3 if targets.mode == "position" else 6
    if chain.n <= rows:
        assert diff[conv].max() <= 1e-9  # the same solution, to rounding
    else:  # redundant: the solutions form a manifold; rounding may move along it, never off it
        R, p, J = jacobian(chain, ref[0][conv])
        _, Jt = nm._task(targets.take(conv), R, p, J, max(chain.reach, 1.0) / 4.0)
        moved = got[0][conv] - ref[0][conv]
        assert np.abs(moved).max() <= 1e-5
        assert np.abs(np.einsum("imn,in->im", Jt, moved)).max() <= 1e-9 * max(1.0, chain.reach)
    assert (got[1][conv] <= nm.TOL_CM).all() and (got[2][conv] <= nm.TOL_RAD).all() | (targets.mode == "position")
    R2, p2 = fk(chain, got[0])  # the C residuals are the numpy residuals of the C joints
    pos, rot = nm.residuals(targets, R2, p2)
    assert np.allclose(pos, got[1], rtol=1e-6, atol=1e-12)
    assert np.allclose(rot, got[2], rtol=1e-6, atol=1e-12, equal_nan=True)


#: A 6R arm with a prismatic joint, clipped (not full-turn) limits, a reversed joint and a tool.
SIX_MIXED = {"joint": [{"a": 0, "alpha": 90, "d": 30}, {"a": 40, "alpha": 0, "limits": [-100, 80]},
                       {"type": "prismatic", "a": 5, "alpha": -90, "d": 10, "limits": [0, 20]},
                       {"a": 0, "alpha": 90, "d": 35, "scale": -1}, {"a": 0, "alpha": -90, "limits": [-120, 120]},
                       {"a": 0, "alpha": 0, "d": 5}],
             "tool": {"xyz": [1, 2, 10], "rpy": [5, -10, 15]}}


def _hard_starts(chain, q_target, q0):
    """Starts that take the lanes' scalar fallbacks: a huge angle (libm's sin and cos), the last
    joint half a turn off the target (a rotation error of exactly pi), a joint out of its turn."""
    q0 = q0.copy()
    q0[0, 0] = 3e5
    q0[1] = q_target[1]
    q0[1, -1] += np.pi
    q0[2, 0] = chain.upper[0] + 1.0
    return q0


@pytest.mark.skipif(not lmkernel.lanes_available(), reason="no AVX2: rows are solved one at a time anyway")
@pytest.mark.parametrize("name", ["puma560", "toz-6r", "six-mixed"])
def test_lanes_are_bit_identical_to_rows(name):
    """Pose mode on six joints runs four rows per vector (csrc/lm_lanes.c) where the CPU has AVX2:
    the same bits as one row at a time, in every output, fallback lanes included."""
    chain = (parse_chain(SIX_MIXED, "six-mixed.toml") if name == "six-mixed" else load_chain(shipped_arm(name)))
    rng = np.random.default_rng(6)
    q_target = random_joints(chain, 301, rng)
    R, p = fk(chain, q_target)
    targets = nm.Targets("pose", p, R)
    q0 = _hard_starts(chain, q_target, random_joints(chain, 301, rng))
    switch = ctypes.c_int.in_dll(lmkernel._library(), "lm_use_lanes")
    out = {}
    try:
        for lanes in (1, 0):
            switch.value = lanes
            out[lanes] = lmkernel.levenberg_marquardt(chain, targets, q0, return_iterations=True)
    finally:
        switch.value = 1
    assert all(np.array_equal(a, b, equal_nan=True) for a, b in zip(out[0], out[1]))
    assert out[1][3].mean() > 0.3 and out[1][3][1]  # converged rows, the half turn among them


@pytest.mark.parametrize("all_solutions", [False, True])
def test_multistart_backends_agree(all_solutions):
    chain, targets, q0 = _problem("puma560:pose", 60, 2)
    kw = {"all_solutions": all_solutions, "starts": 24 if all_solutions else None, "q0": None if all_solutions else q0}
    ref = multistart.solve(chain, targets, backend="numpy", **kw)
    got = multistart.solve(chain, targets, backend="c", **kw)
    assert (ref.row == got.row).all() and (ref.status == got.status).all()
    assert np.abs(ref.q - got.q).max() <= 1e-9
    assert (got.status == nm.OK).all()


def test_backend_checked():
    chain, targets, q0 = _problem("puma560:pose", 2, 3)
    with pytest.raises(ValueError, match="backend"):
        multistart.solve(chain, targets, backend="fortran")


@pytest.mark.parametrize("opt", [pytest.param("-O2", marks=pytest.mark.slow), "-O3"])
def test_strict_warnings(opt, tmp_path):
    """The kernel and its driver compile clean under -Wall -Wextra -Werror -std=c99 -pedantic."""
    flags = (opt,) + csolver.WARN_FLAGS[1:]
    assert {"-Wall", "-Wextra", "-Werror", "-std=c99", "-pedantic"} <= set(flags)
    directory = lmkernel.build_driver().parent  # the sources, as the sanitizer build sees them
    sources = [str(directory / name) for name in lmkernel.C_FILES + (lmkernel.DRIVER,)]
    result = subprocess.run([cbuild.compiler(), *flags, "-c", "-I", str(directory), *sources],
                            capture_output=True, text=True, cwd=tmp_path)
    assert result.returncode == 0 and not result.stderr, result.stderr


@pytest.mark.parametrize("name", CASES)
def test_sanitizer_driver_matches_the_library(name):
    """ASan + UBSan build, fed rows as text (one call, as the library): no report, and bit-identical
    to the ctypes library; the first starts take the lanes' scalar fallbacks where lanes run."""
    chain, targets, q0 = _problem(name, 40, 4, hard=True)
    out = csolver.run_test_driver(lmkernel.build_driver(), lmkernel.driver_input(chain, targets, q0), timeout=120)
    rows = np.array([[float(v) for v in line.split()] for line in out])
    q, pos, rot, *_, steps = lmkernel.levenberg_marquardt(chain, targets, q0, return_iterations=True)
    assert rows.shape == (len(q0), chain.n + 3)
    assert np.array_equal(rows[:, :chain.n], q) and np.array_equal(rows[:, chain.n], pos)
    assert np.array_equal(rows[:, chain.n + 1], rot, equal_nan=True) and (rows[:, -1] == steps).all()


def test_numpy_fallback_without_a_compiler(monkeypatch):
    """No working C compiler: multistart falls back to the numpy reference, same answers."""
    chain, targets, q0 = _problem("toz-6r:pose", 20, 5)
    with_c = multistart.solve(chain, targets, q0=q0)
    monkeypatch.setattr(lmkernel, "available", lambda: False)
    monkeypatch.setattr(lmkernel, "levenberg_marquardt", None)  # would raise if called
    alone = multistart.solve(chain, targets, q0=q0)
    assert (alone.status == with_c.status).all() and np.abs(alone.q - with_c.q).max() <= 1e-9
