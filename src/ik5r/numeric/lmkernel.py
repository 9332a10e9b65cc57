"""The C twin of :func:`ik5r.numeric.solver.levenberg_marquardt` (``csrc/lm_kernel.c``), loaded via ctypes.

The numpy function is the reference: it steps every row of a batch together, so a batch costs as
many numpy passes as its slowest row needs. The C kernel runs the same iteration row by row, each
row stopping when it is done, with no array temporaries. Built with the host compiler through the
firmware solver's cache (:func:`ik5r.core.cbuild.keyed_dir`); :func:`available` is False
when no compiler works, and callers fall back to numpy.
"""

from __future__ import annotations

import ctypes
import functools
from importlib import resources
from pathlib import Path

import numpy as np

from ik5r.core import cbuild
from ik5r.core.chain import Chain, jacobian

from . import solver as nm

MAX_JOINTS = 7
SOURCES = ("lm_kernel.c", "lm_kernel.h")
DRIVER = "lm_driver.c"
LIB_FLAGS = ("-O3", "-std=c99", "-pedantic", "-Wall", "-Wextra", "-Werror", "-fPIC", "-shared")
MODES = {"pose": 0, "position": 1, "direction": 2}
_D7 = ctypes.c_double * MAX_JOINTS


class LMChain(ctypes.Structure):
    _fields_ = [("n", ctypes.c_int), ("mode", ctypes.c_int), ("consts", (ctypes.c_double * 12) * (MAX_JOINTS + 1)),
                ("offset", _D7), ("scale", _D7), ("lower", _D7), ("upper", _D7),
                ("kind", ctypes.c_int * MAX_JOINTS), ("weight", ctypes.c_double)]


class LMParams(ctypes.Structure):
    _fields_ = [("iterations", ctypes.c_int), ("extra", ctypes.c_int), ("tol_cm", ctypes.c_double),
                ("tol_rad", ctypes.c_double), ("stop", ctypes.c_double), ("close", ctypes.c_double),
                ("damping", ctypes.c_double), ("hopeless", ctypes.c_double), ("give_up", ctypes.c_int)]


def source_files() -> dict[str, bytes]:
    """The kernel's C sources, name -> bytes."""
    base = resources.files("ik5r.numeric").joinpath("csrc")
    return {name: base.joinpath(name).read_bytes() for name in SOURCES}


def build(flags: tuple[str, ...] = LIB_FLAGS) -> Path:
    """The kernel's shared library, compiled once per (sources, compiler, flags) hash."""
    directory = cbuild.keyed_dir("lm", source_files(), flags)
    return cbuild.compile_cached(directory, "liblm.so", flags, ("lm_kernel.c",))


def build_driver(flags: tuple[str, ...] = cbuild.SANITIZE_FLAGS) -> Path:
    """The text driver (csrc/lm_driver.c + the kernel), by default under ASan + UBSan."""
    contents = {**source_files(), DRIVER: resources.files("ik5r.numeric").joinpath("csrc", DRIVER).read_bytes()}
    directory = cbuild.keyed_dir("lm-driver", contents, flags)
    return cbuild.compile_cached(directory, "lm_driver", flags, ("lm_kernel.c", DRIVER), libs=("-lm",))


def driver_input(chain: Chain, targets: nm.Targets, q0, *, iterations=60, polish=True, damping=0.1) -> list[str]:
    """The driver's stdin for LM from q0 (M, n) on targets (M rows), as levenberg_marquardt."""
    s = chain_struct(chain, targets.mode)
    lines = [f"{s.n} {s.mode} {s.weight!r}"]
    lines += [" ".join(repr(v) for v in s.consts[i]) for i in range(chain.n + 1)]
    lines += [f"{s.offset[i]!r} {s.scale[i]!r} {s.lower[i]!r} {s.upper[i]!r} {s.kind[i]}" for i in range(chain.n)]
    lines.append(f"{iterations} {nm._EXTRA if polish else 1} {nm.TOL_CM!r} {nm.TOL_RAD!r} {nm._STOP!r} "
                 f"{nm._CLOSE!r} {damping!r} {nm._HOPELESS!r} {nm._GIVE_UP}")
    for i, q in enumerate(np.asarray(q0, dtype=np.float64)):
        parts = [targets.p[i]] + ([targets.R[i].ravel()] if targets.mode == "pose" else [])
        parts += ([targets.a[i]] if targets.mode == "direction" else []) + [q]
        lines.append(" ".join(repr(float(v)) for v in np.concatenate(parts)))
    return lines


@functools.lru_cache(maxsize=1)
def _library():
    lib = ctypes.CDLL(str(build()))
    fn = lib.lm_solve_rows
    fn.restype = ctypes.c_int
    fn.argtypes = [ctypes.POINTER(LMChain), ctypes.POINTER(LMParams), ctypes.c_size_t] + [ctypes.c_void_p] * 9
    return lib


def available() -> bool:
    """True when the kernel builds and loads here."""
    try:
        _library()
    except (OSError, RuntimeError):
        return False
    return True


def chain_struct(chain: Chain, mode: str) -> LMChain:
    """The kernel's view of a chain in a task mode."""
    s = LMChain()
    s.n, s.mode, s.weight = chain.n, MODES[mode], max(chain.reach, 1.0) / 4.0
    for i, c in enumerate(chain.consts):
        s.consts[i][:] = [float(v) for v in np.asarray(c)[:3, :4].ravel()]
    wraps = chain.wraps()
    for i in range(chain.n):
        s.offset[i], s.scale[i] = chain.offset[i], chain.scale[i]
        s.lower[i], s.upper[i] = chain.lower[i], chain.upper[i]
        s.kind[i] = 1 if chain.prismatic[i] else 2 if wraps[i] else 0
    return s


def _contiguous(a):
    return None if a is None else np.ascontiguousarray(a, dtype=np.float64)


def levenberg_marquardt(chain: Chain, targets: nm.Targets, q0, *, rows=None, iterations=60, tol_cm=nm.TOL_CM,
                        tol_rad=nm.TOL_RAD, polish=True, damping=0.1, give_up=nm._GIVE_UP, rank_check=True,
                        return_iterations=False):
    """:func:`ik5r.numeric.solver.levenberg_marquardt` in C. ``rows`` (M,) picks the target of each start
    (default: row i solves target i), so repeated targets are not copied. Returns the same tuple
    (q, pos_err, rot_err, converged, singular), plus the steps tried per row when asked. Without
    ``rank_check``, singular is all False (for callers that check the rank of the rows they keep)."""
    q0 = np.ascontiguousarray(q0, dtype=np.float64).reshape(-1, chain.n)
    count = len(q0)
    rows = np.arange(count) if rows is None else np.asarray(rows)
    rows = np.ascontiguousarray(rows, dtype=np.int64)
    if len(rows) != count or (count and (rows.min() < 0 or rows.max() >= len(targets))):
        raise ValueError("rows must index the targets, one per start")
    p, R, a = _contiguous(targets.p), _contiguous(targets.R), _contiguous(targets.a)
    params = LMParams(iterations, nm._EXTRA if polish else 1, tol_cm, tol_rad, nm._STOP, nm._CLOSE, damping,
                      nm._HOPELESS, give_up)
    q, pos, rot = np.empty((count, chain.n)), np.empty(count), np.empty(count)
    steps = np.empty(count, dtype=np.int64)
    ptr = [None if x is None else x.ctypes.data for x in (rows, p, R, a, q0, q, pos, rot, steps)]
    status = _library().lm_solve_rows(ctypes.byref(chain_struct(chain, targets.mode)), ctypes.byref(params),
                                      count, *ptr)
    if status != 0:
        raise ValueError("lm_solve_rows refused the chain or parameters")
    converged = (pos <= tol_cm) & ~(rot > tol_rad)
    singular = np.zeros(count, dtype=bool)
    failed = np.nonzero(~converged)[0]
    if len(failed) and rank_check:  # as numpy: rank of the task Jacobian where the failed rows ended
        R2, p2, J = jacobian(chain, q[failed])
        _, Jt = nm._task(targets.take(rows[failed]), R2, p2, J, max(chain.reach, 1.0) / 4.0)
        singular[failed] = nm._rank_lost(Jt)
    out = (q, pos, rot, converged, singular)
    return out + (steps,) if return_iterations else out
