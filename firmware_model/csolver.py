"""Build the C solver ``ik5r.c`` with the host compiler and call it from Python through ctypes.

The generated ``ik5r_config.h`` and copies of the C sources are written to a build directory in a
cache, never into the source tree: ``$IK5R_CACHE_DIR``, else ``$XDG_CACHE_HOME/ik5r``, else
``~/.cache/ik5r``. The directory is keyed by a hash of (sources, generated header, compiler,
flags), so a change of config, arm, source or flag rebuilds and an unchanged one reuses the
shared library. Builds are atomic (temporary file + rename), so concurrent test processes are
safe.

:class:`CSolver` offers ``solve_batch`` with exactly the signature of
:func:`ik5r.firmware_model.model.solve_batch` (minus ``k``, bound at construction; the module-level
:func:`solve_batch` takes ``k`` first like the model) and batch versions of the building blocks.
Every input must be a word of the config (signed ``width`` bits): that is the C's contract, and
``ValueError`` is raised otherwise.
"""

from __future__ import annotations

import ctypes
import os
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from ik5r.core.cbuild import SANITIZE_FLAGS, compile_cached, compiler, keyed_dir
from ik5r.core.fxconfig import Constants

from .codegen import HEADER_NAME, generate_header

SOURCE_DIR = Path(__file__).resolve().parent
#: The solver's sources (the header ik5r_config.h is generated).
SOURCES = ("ik5r.c", "ik5r.h")
DRIVER = "test_driver.c"
#: Shared library for ctypes.
LIB_FLAGS = ("-O2", "-std=c99", "-fPIC", "-shared")
#: Strict warnings, as the firmware build should use them.
WARN_FLAGS = ("-O2", "-std=c99", "-pedantic", "-Wall", "-Wextra", "-Werror")


def build_dir(k: Constants, kind: str, files: tuple[str, ...], flags: tuple[str, ...]) -> Path:
    """A cache directory holding the generated header and copies of ``files``, keyed by a hash."""
    contents = {name: (SOURCE_DIR / name).read_bytes() for name in files}
    contents[HEADER_NAME] = generate_header(k).encode()
    return keyed_dir(f"{k.cfg.name}-{kind}", contents, flags)


def build_library(k: Constants, flags: tuple[str, ...] = LIB_FLAGS) -> Path:
    """The shared library of the solver for ``k`` (built once per hash)."""
    directory = build_dir(k, "lib", SOURCES, flags)
    return compile_cached(directory, "libik5r.so", flags, ("ik5r.c",))


def build_test_driver(k: Constants, sanitize: bool = True) -> Path:
    """The standalone test driver (test_driver.c + ik5r.c), by default with ASan + UBSan."""
    flags = SANITIZE_FLAGS if sanitize else ("-O2", "-std=c99")
    directory = build_dir(k, "asan" if sanitize else "driver", SOURCES + (DRIVER,), flags)
    return compile_cached(directory, "ik5r_test_driver", flags, ("ik5r.c", DRIVER))


def warnings_check(k: Constants, flags: tuple[str, ...] = WARN_FLAGS) -> subprocess.CompletedProcess:
    """Compile ik5r.c and test_driver.c to objects with ``flags`` (strict warnings); not cached."""
    directory = build_dir(k, "warn", SOURCES + (DRIVER,), flags)
    with tempfile.TemporaryDirectory() as out:
        cmd = [compiler(), *flags, "-c", "-I", str(directory), str(directory / "ik5r.c"),
               str(directory / DRIVER)]
        return subprocess.run(cmd, capture_output=True, text=True, cwd=out)


def run_test_driver(driver: Path, lines: list[str], timeout: float = 600) -> list[str]:
    """Feed command lines to the driver; returns its output lines. Raises on a non-zero exit
    or on anything written to stderr (a sanitizer report)."""
    result = subprocess.run([str(driver)], input="\n".join(lines) + "\n", capture_output=True,
                            text=True, timeout=timeout, env={**os.environ, "ASAN_OPTIONS": "detect_leaks=1",
                                                             "UBSAN_OPTIONS": "print_stacktrace=1"})
    if result.returncode != 0 or result.stderr:
        raise RuntimeError(f"test driver exit {result.returncode}:\n{result.stderr[-4000:]}")
    return result.stdout.splitlines()


# --------------------------------------------------------------------------------------------

_P = ctypes.c_void_p
_SIZE = ctypes.c_size_t


def _ptr(array: np.ndarray) -> int:
    return array.ctypes.data


class CSolver:
    """The C solver for the config and arm of ``k``, loaded through ctypes."""

    def __init__(self, k: Constants):
        self.k = k
        self.path = build_library(k)
        lib = self.lib = ctypes.CDLL(str(self.path))
        lib.ik5r_self_check.restype = ctypes.c_int
        lib.ik5r_self_check.argtypes = []
        lib.ik5r_config_name.restype = ctypes.c_char_p
        lib.ik5r_solve_batch.restype = None
        lib.ik5r_solve_batch.argtypes = [_SIZE] + [_P] * 10
        lib.ik5r_atan2_batch.argtypes = [_SIZE] + [_P] * 5
        lib.ik5r_rotate_batch.argtypes = [_SIZE] + [_P] * 6
        lib.ik5r_acos_batch.argtypes = [_SIZE] + [_P] * 4
        lib.ik5r_sqrt_word_batch.argtypes = [_SIZE] + [_P] * 3
        lib.ik5r_isqrt64_batch.argtypes = [_SIZE] + [_P] * 4
        for name in ("ik5r_atan2_batch", "ik5r_rotate_batch", "ik5r_acos_batch",
                     "ik5r_sqrt_word_batch", "ik5r_isqrt64_batch"):
            getattr(lib, name).restype = None
        check = lib.ik5r_self_check()
        if check != 0:
            raise RuntimeError(f"ik5r_self_check failed ({check}): the C semantics relied on do not hold")
        if lib.ik5r_config_name().decode() != k.cfg.name:
            raise RuntimeError("library built for another config")

    # -- helpers -----------------------------------------------------------------------------

    def _words(self, values, name: str, shape=None) -> np.ndarray:
        array = np.asarray(values)
        if array.dtype.kind not in "biu":
            raise TypeError(f"{name}: integer array expected, got {array.dtype}")
        if shape is not None and array.shape[1:] != shape[1:]:
            raise ValueError(f"{name}: shape {array.shape}, expected (N, {shape[1]})")
        if array.size and (array.min() < self.k.word_min or array.max() > self.k.word_max):
            raise ValueError(f"{name}: values outside the {self.k.cfg.width}-bit word range")
        return np.ascontiguousarray(array, dtype=np.int32)

    @staticmethod
    def _flags(values, count: int) -> np.ndarray:
        return np.ascontiguousarray(np.broadcast_to(np.asarray(values, dtype=bool), (count,)), dtype=np.uint8)

    # -- the solver --------------------------------------------------------------------------

    def solve_batch(self, p_l, a_u, n_u, o_u, has_roll, shoulder_back, elbow_down, q5_default_a):
        """ik5r_solve over a batch: the signature and results of model.solve_batch (minus k).

        p_l, a_u, n_u, o_u: (N, 3) integer arrays (n_u, o_u read only where has_roll; may be None
        when no row has roll); has_roll, shoulder_back, elbow_down: (N,) bools; q5_default_a: (N,).
        Returns (q_a (N, 5) int64, status (N,) int64).
        """
        p = self._words(p_l, "p_l", (0, 3))
        count = len(p)
        a = self._words(a_u, "a_u", (0, 3))
        roll = self._flags(has_roll, count)
        rows = roll.astype(bool)[:, None]
        n = self._words(np.where(rows, n_u, 0) if n_u is not None else np.zeros((count, 3), np.int64), "n_u", (0, 3))
        o = self._words(np.where(rows, o_u, 0) if o_u is not None else np.zeros((count, 3), np.int64), "o_u", (0, 3))
        if (n_u is None or o_u is None) and roll.any():
            raise ValueError("has_roll set but n_u/o_u missing")
        back = self._flags(shoulder_back, count)
        down = self._flags(elbow_down, count)
        q5 = self._words(np.broadcast_to(np.asarray(q5_default_a), (count,)), "q5_default_a")
        if not (len(a) == len(n) == len(o) == count):
            raise ValueError("inputs differ in length")
        q_a = np.empty((count, 5), dtype=np.int32)
        status = np.empty(count, dtype=np.uint32)
        self.lib.ik5r_solve_batch(count, _ptr(p), _ptr(a), _ptr(n), _ptr(o), _ptr(roll), _ptr(back),
                                  _ptr(down), _ptr(q5), _ptr(q_a), _ptr(status))
        return q_a.astype(np.int64), status.astype(np.int64)

    # -- building blocks ---------------------------------------------------------------------

    def atan2(self, y, x):
        """cordic_atan2 element-wise: (angle_a, magnitude, zero) as int64, int64, bool arrays."""
        y, x = np.broadcast_arrays(np.asarray(y), np.asarray(x))
        y, x = self._words(y.ravel(), "y"), self._words(x.ravel(), "x")
        count = len(y)
        angle, mag, zero = np.empty(count, np.int32), np.empty(count, np.int32), np.empty(count, np.uint8)
        self.lib.ik5r_atan2_batch(count, _ptr(y), _ptr(x), _ptr(angle), _ptr(mag), _ptr(zero))
        return angle.astype(np.int64), mag.astype(np.int64), zero.astype(bool)

    def rotate(self, x, y, angle_a):
        """cordic_rotate element-wise: (x', y', flags) as int64 arrays."""
        x, y, angle_a = np.broadcast_arrays(np.asarray(x), np.asarray(y), np.asarray(angle_a))
        x, y, ang = self._words(x.ravel(), "x"), self._words(y.ravel(), "y"), self._words(angle_a.ravel(), "angle_a")
        count = len(x)
        xo, yo, flags = np.empty(count, np.int32), np.empty(count, np.int32), np.empty(count, np.uint32)
        self.lib.ik5r_rotate_batch(count, _ptr(x), _ptr(y), _ptr(ang), _ptr(xo), _ptr(yo), _ptr(flags))
        return xo.astype(np.int64), yo.astype(np.int64), flags.astype(np.int64)

    def acos(self, x_u):
        """cordic_acos element-wise: (angle_a, sine_u, flags) as int64 arrays."""
        x = self._words(np.asarray(x_u).ravel(), "x_u")
        count = len(x)
        angle, sine, flags = np.empty(count, np.int32), np.empty(count, np.int32), np.empty(count, np.uint32)
        self.lib.ik5r_acos_batch(count, _ptr(x), _ptr(angle), _ptr(sine), _ptr(flags))
        return angle.astype(np.int64), sine.astype(np.int64), flags.astype(np.int64)

    def sqrt_word(self, x, frac):
        """sqrt_word element-wise (frac scalar or array): int64 roots."""
        x, frac = np.broadcast_arrays(np.asarray(x), np.asarray(frac))
        x = self._words(x.ravel(), "x")
        frac = np.ascontiguousarray(frac.ravel(), dtype=np.int32)
        if frac.size and (frac.min() < 0 or frac.max() > 63 - self.k.cfg.width):
            raise ValueError("frac out of range")
        root = np.empty(len(x), np.int64)
        self.lib.ik5r_sqrt_word_batch(len(x), _ptr(x), _ptr(frac), _ptr(root))
        return root

    def isqrt64(self, radicand, bits, nearest):
        """isqrt element-wise over uint64 radicands (bits, nearest scalar or arrays): uint64 roots."""
        radicand = np.asarray(radicand, dtype=np.uint64)
        radicand, bits, nearest = np.broadcast_arrays(radicand, np.asarray(bits), np.asarray(nearest))
        radicand = np.ascontiguousarray(radicand.ravel(), dtype=np.uint64)
        bits = np.ascontiguousarray(bits.ravel(), dtype=np.int32)
        if bits.size and (bits.min() < 0 or bits.max() > 64):
            raise ValueError("bits out of [0, 64]")
        nearest = np.ascontiguousarray(nearest.ravel(), dtype=bool).astype(np.uint8)
        root = np.empty(len(radicand), np.uint64)
        self.lib.ik5r_isqrt64_batch(len(radicand), _ptr(radicand), _ptr(bits), _ptr(nearest), _ptr(root))
        return root


_SOLVERS: dict[int, CSolver] = {}


def solver(k: Constants) -> CSolver:
    """A cached CSolver per Constants object."""
    key = id(k)
    if key not in _SOLVERS or _SOLVERS[key].k is not k:
        _SOLVERS[key] = CSolver(k)
    return _SOLVERS[key]


def solve_batch(k: Constants, p_l, a_u, n_u, o_u, has_roll, shoulder_back, elbow_down, q5_default_a):
    """The C solver with exactly the signature of model.solve_batch."""
    return solver(k).solve_batch(p_l, a_u, n_u, o_u, has_roll, shoulder_back, elbow_down, q5_default_a)
