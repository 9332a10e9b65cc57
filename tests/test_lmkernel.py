"""The C LM kernel (ik5r.numeric.lmkernel, csrc/lm_kernel.c) against the numpy reference
(ik5r.numeric.solver.levenberg_marquardt), its strict-warning build and its sanitizer build."""

from __future__ import annotations

import subprocess
import tomllib

import numpy as np
import pytest
from test_numeric import PRISMATIC_ARM

from ik5r.core import cbuild
from ik5r.core.chain import fk, jacobian, load_chain, parse_chain, random_joints, shipped_arm
from ik5r.firmware import csolver
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


def _problem(name, count, seed):
    chain, mode = _case(name)
    rng = np.random.default_rng(seed)
    R, p = fk(chain, random_joints(chain, count, rng))
    targets = nm.Targets(mode, p, R if mode == "pose" else None, R[:, :, 2] if mode == "direction" else None)
    return chain, targets, random_joints(chain, count, rng)


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


@pytest.mark.parametrize("opt", ["-O2", "-O3"])
def test_strict_warnings(opt, tmp_path):
    """The kernel and its driver compile clean under -Wall -Wextra -Werror -std=c99 -pedantic."""
    flags = (opt,) + csolver.WARN_FLAGS[1:]
    assert {"-Wall", "-Wextra", "-Werror", "-std=c99", "-pedantic"} <= set(flags)
    directory = lmkernel.build_driver().parent  # the sources, as the sanitizer build sees them
    result = subprocess.run([cbuild.compiler(), *flags, "-c", "-I", str(directory), str(directory / "lm_kernel.c"),
                             str(directory / lmkernel.DRIVER)], capture_output=True, text=True, cwd=tmp_path)
    assert result.returncode == 0 and not result.stderr, result.stderr


@pytest.mark.parametrize("name", CASES)
def test_sanitizer_driver_matches_the_library(name):
    """ASan + UBSan build, fed rows as text: no report, and bit-identical to the ctypes library."""
    chain, targets, q0 = _problem(name, 40, 4)
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
