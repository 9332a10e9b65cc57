"""A table of first starts for :mod:`ik5r.numeric.multistart`: joint vectors whose FK lands near each target.

Built once per arm and mode (cached in the process): ``SIZE`` joint vectors drawn uniformly in the
limits from a fixed seed, their FK, and a grid over the task space: the tool point in ``POINT_CELLS``
cells per axis of the table's bounding box, and (pose mode) the orientation as a unit quaternion
(sign fixed by w >= 0) in ``TURN_CELLS`` cells per component, or (direction mode) the tool z axis in
``TURN_CELLS`` cells per component. Each occupied cell keeps its first ``DEPTH`` table entries. A target's start
is the first entry of its own cell (its second start the second entry), found by a sorted-array search (vectorised, about 0.5 us per pose; a
k-d tree on the same features costs 4 to 10 us per pose and gives no better starts); a target whose
cell is empty gets none (the caller draws a uniform start instead). The lookup depends on the
target alone, so a pose gets the same start whatever else is in the batch.

Why: from a uniform start LM needs about 14 steps on the PUMA 560 and 7% of starts fail; from the
table's start (within a cell of the target) about 9, and 1.3% fail. On
Toz's 6R 39% of uniform starts fail, 25% of the table's first, and where that one fails the
cell's second entry converges 59% of the time against 51% for a uniform start.

The build (about 90 ms of CPU) is kept on disk in the cache of the C builds (``$IK5R_CACHE_DIR``,
else ``~/.cache/ik5r``), keyed by a hash of the arm's numbers, the mode, the table's parameters and
the sources that shape it (this module and :mod:`ik5r.core.chain`): a later process loads it in a few
milliseconds, and the entries are the same numbers either way.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numpy as np

from ik5r.core import cbuild
from ik5r.core import chain as chain_module
from ik5r.core.chain import Chain, fk

from . import solver as nm

SIZE = 100_000
POINT_CELLS = 6
TURN_CELLS = 4
DEPTH = 4  # entries kept per cell: the first starts of a pose
_SEED = 0x5EED7AB1E
_CACHE: dict[tuple, "StartTable"] = {}


def _quaternion(R) -> np.ndarray:
    """(N, 4) unit quaternions (w >= 0, x, y, z) of rotation matrices (N, 3, 3), each component from
    its own diagonal combination (no branches; precise enough for a grid, and 20 times faster than
    scipy's Rotation.from_matrix, which orthonormalises first)."""
    d0, d1, d2 = R[:, 0, 0], R[:, 1, 1], R[:, 2, 2]
    mags = 0.5 * np.sqrt(np.maximum(0.0, np.stack([1 + d0 + d1 + d2, 1 + d0 - d1 - d2, 1 - d0 + d1 - d2,
                                                   1 - d0 - d1 + d2], axis=1)))
    signs = np.stack([np.ones(len(R)), R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]],
                     axis=1)
    return np.copysign(mags, signs)


def _turn_features(mode: str, R, a) -> np.ndarray | None:
    """(N, k) orientation features in [-1, 1]: the quaternion (w >= 0) in pose mode, the tool z
    axis in direction mode, none in position mode."""
    if mode == "pose":
        return _quaternion(R)
    if mode == "direction":
        return a
    return None


class StartTable:
    """The table of one arm and mode; ``lookup(targets)`` gives (starts (N, n), found (N,))."""

    def __init__(self, chain: Chain, mode: str, size: int | None = None):
        if mode not in nm.MODES:
            raise ValueError(f"mode must be one of {nm.MODES}, got {mode!r}")
        self.mode, size = mode, SIZE if size is None else size
        unit = np.random.default_rng(_SEED).random((size, chain.n))
        q = chain.lower + unit * (chain.upper - chain.lower)
        R, p = fk(chain, q)
        self.low = p.min(axis=0)
        self.span = np.maximum(p.max(axis=0) - self.low, 1e-12)
        keys = self._keys(p, R, R[:, :, 2])
        order = np.argsort(keys, kind="stable")
        self.keys, first = np.unique(keys[order], return_index=True)
        rank = np.arange(size) - np.repeat(first, np.diff(np.append(first, size)))  # place in its cell
        self.q = np.full((len(self.keys), DEPTH, chain.n), np.nan)
        kept = rank < DEPTH
        self.q[np.searchsorted(self.keys, keys[order][kept]), rank[kept]] = q[order][kept]

    def _keys(self, p, R, a) -> np.ndarray:
        cell = np.clip(((p - self.low) / self.span * POINT_CELLS).astype(np.int64), 0, POINT_CELLS - 1)
        key = np.zeros(len(p), dtype=np.int64)
        for column in cell.T:
            key = key * POINT_CELLS + column
        turn = _turn_features(self.mode, R, a)
        if turn is not None:
            for column in np.clip(((turn + 1.0) * 0.5 * TURN_CELLS).astype(np.int64), 0, TURN_CELLS - 1).T:
                key = key * TURN_CELLS + column
        return key

    def lookup(self, targets: nm.Targets) -> tuple[np.ndarray, np.ndarray]:
        """(N, DEPTH, n) each target's starts (the entries of its cell in table order; NaN where the
        cell is empty or holds fewer) and (N,) whether its cell has any."""
        if targets.mode != self.mode:
            raise ValueError(f"table of mode {self.mode}, targets of mode {targets.mode}")
        p = np.nan_to_num(targets.p)  # invalid rows are rejected before the lookup is used
        R = None if targets.R is None else np.nan_to_num(targets.R)
        a = None if targets.a is None else np.nan_to_num(targets.a)
        key = self._keys(p, R, a)
        at = np.minimum(np.searchsorted(self.keys, key), len(self.keys) - 1)
        found = self.keys[at] == key
        return np.where(found[:, None, None], self.q[at], np.nan), found


def _chain_key(chain: Chain, mode: str) -> tuple:
    parts = [np.asarray(c).tobytes() for c in chain.consts]
    return (mode, chain.prismatic, chain.offset, chain.scale, chain.lower.tobytes(), chain.upper.tobytes(),
            tuple(parts))


_STORED = ("keys", "q", "low", "span")


def _disk_path(key: tuple) -> Path:
    digest = hashlib.sha256(repr(key[:4]).encode())
    for part in key[4:-1] + key[-1]:
        digest.update(part)
    digest.update(repr((SIZE, POINT_CELLS, TURN_CELLS, DEPTH, _SEED)).encode())
    for module in (Path(__file__), Path(chain_module.__file__)):
        digest.update(module.read_bytes())
    return cbuild.cache_root() / f"start-table-{digest.hexdigest()[:24]}.npz"


def _load_or_build(chain: Chain, mode: str, path: Path) -> StartTable:
    try:
        with np.load(path) as stored:
            table = StartTable.__new__(StartTable)
            table.mode = mode
            for name in _STORED:
                setattr(table, name, stored[name])
            return table
    except (OSError, KeyError, ValueError):  # absent, unreadable or partial: build it (again)
        pass
    table = StartTable(chain, mode)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        temporary = path.with_name(f"{path.stem}.{os.getpid()}.tmp.npz")
        np.savez(temporary, **{name: getattr(table, name) for name in _STORED})
        os.replace(temporary, path)  # atomic: concurrent processes see the whole file or none
    except OSError:
        pass  # a read-only cache only costs the build next time
    return table


def table_for(chain: Chain, mode: str) -> StartTable:
    """The table of this arm (by its numbers) and mode: from this process's cache, else the disk
    cache, else built (and stored)."""
    key = _chain_key(chain, mode)
    if key not in _CACHE:
        _CACHE[key] = _load_or_build(chain, mode, _disk_path(key))
    return _CACHE[key]
