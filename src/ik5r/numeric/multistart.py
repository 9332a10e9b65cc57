"""Many seeded starts per pose for :mod:`ik5r.numeric.solver`: the first solution, or every distinct one.

``solve(chain, targets, starts=S)`` runs Levenberg-Marquardt from S joint vectors per pose (start 0
is ``q0`` when given; for one solution per pose without it, the first starts are the entries of the
pose's cell in the arm's start table, :mod:`ik5r.numeric.start_table`; the others uniform in the limits). Start k of a pose is a fixed function of
``seed``, the pose's own numbers (their float64 bits) and k (a splitmix64 hash): a pose gets the
same starts, hence the same answer, whatever else is in the batch and wherever it sits in it. With
``all_solutions`` every start runs and the converged ones are
de-duplicated (two solutions are the same when every joint differs by less than ``DISTINCT``, angles
of full-turn joints compared modulo 2 pi); otherwise starts run in rounds, each round only on the
poses still unsolved, and the first converged start answers. Poses with no converged start get one
row with the best start's joints, residuals and status (``singular`` or ``not_converged``).
With the default starts (``starts=None``), a pose still unsolved after ``DEFAULT_STARTS["first"]``
gets more, up to ``ESCALATE_TO`` in rounds of doubling width (starts 33..64, 65..128): the poses
solved earlier run exactly as before (start k is the same whatever the total), only the hard ones
pay (on an unseen modified-DH 6R, 3 of 300 random poses needed more than 32 starts).
"""

from __future__ import annotations

import numpy as np

from ik5r.core.chain import Chain

from . import lmkernel, start_table
from . import solver as nm

DISTINCT = 1e-6
WARM_DAMPING = 1e-6  # initial LM damping (relative) from a start known to be close
TABLE_DAMPING = 1e-3  # initial LM damping from the start table's entry (PUMA 560: 10 steps against 12 at 0.1)
DEFAULT_STARTS = {"first": 32, "all": 128}
_ROUNDS = (1,) * 8 + (2, 4, 8)  # starts per pose in successive rounds of the first-solution search:
# one at a time while many poses are open (a wider round runs starts past the one that converges:
# on Toz's 6R, where 40% of random starts fail, eight rounds of one are 10% faster than 1, 1, 2, 4, 8)
_POLISH_AFTER = 4  # starts tried before the close-but-unsolved poses are polished
ESCALATE_TO = 128  # starts of a pose still unsolved after the default ones (first-solution search)


def _round_widths(starts: int, total: int):
    """Widths of the successive rounds: :data:`_ROUNDS`, the rest of ``starts`` in one round, then
    rounds doubling the starts tried so far until ``total``."""
    begin = 0
    for width in _ROUNDS:
        width = min(width, starts - begin)
        if width <= 0:
            break
        yield width
        begin += width
    if begin < starts:
        yield starts - begin
        begin = starts
    while begin < total:
        width = min(begin, total - begin)
        yield width
        begin += width


_GOLDEN = np.uint64(0x9E3779B97F4A7C15)


def _splitmix(x: np.ndarray) -> np.ndarray:
    """splitmix64's finaliser on uint64 arrays (wrapping arithmetic): a well-mixed 64-bit hash."""
    x = (x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    x = (x ^ (x >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return x ^ (x >> np.uint64(31))


def pose_keys(targets: nm.Targets, seed: int) -> np.ndarray:
    """(N,) uint64: a hash of seed and each pose's numbers (p, and R or a), the key of its starts."""
    parts = [targets.p] + [x.reshape(len(targets), -1) for x in (targets.R, targets.a) if x is not None]
    bits = np.ascontiguousarray(np.concatenate(parts, axis=1), dtype=np.float64).view(np.uint64)
    key = np.full(len(targets), _splitmix(np.array([seed & (2**64 - 1)], dtype=np.uint64) + _GOLDEN)[0])
    for column in bits.T:
        key = _splitmix((key ^ column) + _GOLDEN)
    return key


def _uniform(chain: Chain, keys: np.ndarray, first: int, width: int) -> np.ndarray:
    """(len(keys), width, n): starts first .. first + width - 1 of each key, uniform in the limits."""
    index = (np.arange(first, first + width, dtype=np.uint64)[:, None] * np.uint64(chain.n)
             + np.arange(chain.n, dtype=np.uint64)[None, :] + np.uint64(1))
    bits = _splitmix(keys[:, None, None] + index[None] * _GOLDEN)
    unit = (bits >> np.uint64(11)).astype(np.float64) * 2.0 ** -53
    return chain.lower + unit * (chain.upper - chain.lower)


def _round_starts(chain: Chain, keys: np.ndarray, poses: np.ndarray, first: int, width: int, q0,
                  near=None) -> np.ndarray:
    """(len(poses), width, n) starts first .. first + width - 1 of the given poses (drawn only for
    the poses still open: a pose solved by its first start costs no draw); start k < DEPTH is the
    start table's entry where the pose's cell has one (``near``: the table's entries and each
    pose's cell, :func:`_table_starts`); start 0 is q0 when given."""
    if near is None or first >= near[0].shape[1]:
        q = _uniform(chain, keys[poses], first, width)
    else:  # draw only where the cell has no entry
        q = np.empty((len(poses), width, chain.n))
        entries, cell = near[0], near[1][poses]
        for k in range(first, first + width):
            has = np.zeros(len(poses), dtype=bool) if k >= entries.shape[1] else cell >= 0
            if has.any():
                has[has] = ~np.isnan(entries[cell[has], k, 0])
                q[has, k - first] = entries[cell[has], k]
            q[~has, k - first] = _uniform(chain, keys[poses[~has]], k, 1)[:, 0]
    if q0 is not None and first == 0:
        q0 = np.asarray(q0, dtype=np.float64)
        q[:, 0] = q0[poses] if q0.ndim == 2 else q0
    return q


def _table_starts(chain, targets, todo) -> tuple[np.ndarray, np.ndarray]:
    """The start table's entries (cells, DEPTH, n) and each pose's cell (N,): -1 where it has
    none or the pose is invalid (:mod:`ik5r.numeric.start_table`)."""
    table = start_table.table_for(chain, targets.mode)
    if len(todo) == len(targets):  # all valid: no copy of the targets
        return table.q, table.cells(targets)
    cell = np.full(len(targets), -1)
    if len(todo):
        cell[todo] = table.cells(targets.take(todo))
    return table.q, cell


def _rank_lost_at(chain, targets, rows, q) -> np.ndarray:
    """Whether the task Jacobian at q (M, n) for targets[rows] has lost rank: the ``singular``
    flag of levenberg_marquardt, computed once for the poses left unsolved rather than per run."""
    if not len(rows):
        return np.zeros(0, dtype=bool)
    R, p, J = nm.jacobian(chain, q)
    return nm._rank_lost(nm._task(targets.take(rows), R, p, J, max(chain.reach, 1.0) / 4.0)[1])


def _run(chain, targets, rows, q, backend="auto", **kw):
    """LM from starts q (M, n) on targets[rows]: the C kernel, or the numpy reference in chunks."""
    if backend == "c" or backend == "auto" and lmkernel.available():  # singular: see _rank_lost_at
        return lmkernel.levenberg_marquardt(chain, targets, q, rows=rows, rank_check=False, **kw)
    if backend not in ("auto", "numpy"):
        raise ValueError(f"backend must be auto, c or numpy, got {backend!r}")
    out = [nm.levenberg_marquardt(chain, targets.take(rows[i:i + nm._CHUNK]), q[i:i + nm._CHUNK], **kw)
           for i in range(0, len(rows), nm._CHUNK)]
    return tuple(np.concatenate(parts) for parts in zip(*out)) if out else None


def _distinct(chain: Chain, q: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """keep (P,S): converged candidates not within DISTINCT of an earlier kept one."""
    wraps = chain.wraps()
    keep = np.zeros(ok.shape, dtype=bool)
    for lo in range(0, len(q), 256):
        qq, good = q[lo:lo + 256], ok[lo:lo + 256]
        diff = np.abs(qq[:, :, None, :] - qq[:, None, :, :])
        diff[..., wraps] = np.minimum(diff[..., wraps], 2 * np.pi - diff[..., wraps])
        same = (diff.max(axis=-1) < DISTINCT) & good[:, :, None] & good[:, None, :]
        earlier = np.tril(same, k=-1).any(axis=2)  # same as some earlier converged candidate
        keep[lo:lo + 256] = good & ~earlier
    return keep


_KICKS = np.array([0.0, 1e-4, -1e-4, 1e-3, -1e-3, 1e-2, -1e-2, 0.1, -0.1])
_KICK_ROUNDS = (1, 3, 5, 7, 9)  # end of each round of kicks


def _polish(chain, targets, rows, q, **kw):
    """Rows whose best start stopped close to the target, next to a fold singularity: Gauss-Newton
    sees a minimum there (J^T e = 0) where the true cost has a saddle, or crawls along a narrow
    valley. Restart each from points moved along the Jacobian's weakest joint direction (both ways,
    several sizes) with the long iteration budget; keep the best."""
    weight = max(chain.reach, 1.0) / 4.0
    R, p, J = nm.jacobian(chain, q)
    _, Jt = nm._task(targets.take(rows), R, p, J, weight)
    weakest = np.linalg.svd(Jt)[2][:, -1, :]
    k = len(_KICKS)
    starts = clamp_rows(chain, q[:, None, :] + _KICKS[None, :, None] * weakest[:, None, :])
    qq, pos, rot = starts.copy(), np.full((len(rows), k), np.inf), np.full((len(rows), k), np.inf)
    conv, sing = np.zeros((len(rows), k), dtype=bool), np.zeros((len(rows), k), dtype=bool)
    open_, lo = np.arange(len(rows)), 0
    for hi in _KICK_ROUNDS:  # in order, only for rows no earlier kick solved: the same pick, fewer runs
        out = _run(chain, targets, np.repeat(rows[open_], hi - lo), starts[open_, lo:hi].reshape(-1, chain.n), **kw)
        for array, value in zip((qq, pos, rot, conv, sing), out):
            array[open_, lo:hi] = value.reshape(len(open_), hi - lo, *value.shape[1:])
        open_, lo = open_[~conv[open_, lo:hi].any(axis=1)], hi
        if not len(open_):
            break
    score = pos + np.where(np.isnan(rot), 0.0, rot)
    pick = np.where(conv.any(axis=1), np.argmax(conv, axis=1), np.argmin(score, axis=1))
    at = np.arange(len(rows))
    return qq[at, pick], pos[at, pick], rot[at, pick], conv[at, pick], sing[at, pick]


def _polish_close(chain, targets, todo, solved, best_score, best, kw):
    """Polish (in place) the unsolved poses whose best start stopped within _CLOSE of the target,
    once: they sit at a fold, where more random starts rarely help."""
    close = np.nonzero(~solved & (best_score <= nm._CLOSE))[0]
    if not len(close):
        return
    out = _polish(chain, targets, todo[close], best[0][close], **kw)
    for array, value in zip(best, (out[0], out[1], out[2], out[4])):
        array[close] = value
    solved[close] = out[3]
    best_score[close] = np.inf  # later rounds replace them only with a converged start


def clamp_rows(chain, q):
    return nm.clamp(chain, q.reshape(-1, chain.n)).reshape(q.shape)


def _failed_rows(poses, best_q, best_pos, best_rot, best_sing):
    status = np.where(best_sing, nm.SINGULAR, nm.NOT_CONVERGED)
    return nm.Solutions(poses, best_q, status, best_pos, best_rot)


def _collect(parts: list[nm.Solutions]) -> nm.Solutions:
    sol = nm.Solutions(*(np.concatenate([getattr(s, f) for s in parts])
                         for f in ("row", "q", "status", "pos_err", "rot_err")))
    order = np.argsort(sol.row, kind="stable")
    return nm.Solutions(sol.row[order], sol.q[order], sol.status[order], sol.pos_err[order], sol.rot_err[order])


def _prechecked(chain, targets):
    pre = nm.check_targets(chain, targets)
    bad = np.nonzero(pre != nm.OK)[0]
    nan = np.full(len(bad), np.nan)
    rejected = nm.Solutions(bad, np.full((len(bad), chain.n), np.nan), pre[bad], nan, nan.copy())
    return np.nonzero(pre == nm.OK)[0], rejected


def solve_all(chain: Chain, targets: nm.Targets, starts: int, q0=None, seed: int = 0, **kw) -> nm.Solutions:
    """Every distinct converged solution of every pose."""
    todo, rejected = _prechecked(chain, targets)
    qs = _round_starts(chain, pose_keys(targets, seed), todo, 0, starts, q0)
    rows = np.repeat(todo, starts)
    q, pos, rot, conv, sing = _run(chain, targets, rows, qs.reshape(-1, chain.n), polish=False, **kw)
    close = np.nonzero(~conv & (pos + np.where(np.isnan(rot), 0.0, rot) <= nm._CLOSE))[0]
    if len(close):
        q[close], pos[close], rot[close], conv[close], sing[close] = _polish(chain, targets, rows[close], q[close], **kw)
    shape = (len(todo), starts)
    keep = _distinct(chain, q.reshape(*shape, chain.n), conv.reshape(shape)).reshape(-1)
    found = nm.Solutions(rows[keep], q[keep], np.full(keep.sum(), nm.OK), pos[keep], rot[keep])
    none = ~conv.reshape(shape).any(axis=1)
    best = np.argmin(np.where(np.isnan(rot), 0.0, rot).reshape(shape) + pos.reshape(shape), axis=1)
    flat = np.arange(len(todo)) * starts + best
    sel = flat[none]
    failed = _failed_rows(todo[none], q[sel], pos[sel], rot[sel], _rank_lost_at(chain, targets, todo[none], q[sel]))
    return _collect([found, failed, rejected])


def solve_first(chain: Chain, targets: nm.Targets, starts: int, q0=None, seed: int = 0, warm=False,
                table=True, escalate: int | None = None, **kw) -> nm.Solutions:
    """One solution per pose: the first start (in order) that converges. ``warm``: q0 is close to
    the solution (e.g. the previous point of a path): its first step is barely damped. ``table``
    (when q0 is not given): the first starts are the start table's entries of the pose's cell.
    ``escalate``: the poses unsolved after ``starts`` get more, up to this many in all."""
    todo, rejected = _prechecked(chain, targets)
    keys = pose_keys(targets, seed)
    near = _table_starts(chain, targets, todo) if q0 is None and table else None
    n = chain.n
    best_q = np.full((len(todo), n), np.nan)
    best_pos = np.full(len(todo), np.inf)
    best_rot = np.full(len(todo), np.inf)
    best_score = np.full(len(todo), np.inf)
    best_sing = np.zeros(len(todo), dtype=bool)
    solved = np.zeros(len(todo), dtype=bool)
    begin = 0
    total = max(starts, escalate or 0)
    for width in _round_widths(starts, total):
        open_ = np.nonzero(~solved)[0]
        if not len(open_):
            break
        qs = _round_starts(chain, keys, todo[open_], begin, width, q0, near)
        damping = (WARM_DAMPING if warm and begin == 0 else
                   TABLE_DAMPING if near is not None and begin < start_table.DEPTH else None)
        q, pos, rot, conv, sing = _run(chain, targets, np.repeat(todo[open_], width),
                                       qs.reshape(-1, n), polish=begin == 0,
                                       **({} if damping is None else {"damping": damping}), **kw)
        shape = (len(open_), width)
        conv, score = conv.reshape(shape), (pos + np.where(np.isnan(rot), 0.0, rot)).reshape(shape)
        any_conv = conv.any(axis=1)
        pick = np.where(any_conv, np.argmax(conv, axis=1), np.argmin(score, axis=1))
        flat = np.arange(len(open_)) * width + pick
        better = any_conv | (score[np.arange(len(open_)), pick] < best_score[open_])
        upd, sel = open_[better], flat[better]
        best_q[upd], best_pos[upd], best_rot[upd], best_sing[upd] = q[sel], pos[sel], rot[sel], sing[sel]
        best_score[upd] = score[np.arange(len(open_)), pick][better]
        solved[open_] = any_conv
        begin += width
        if begin in (_POLISH_AFTER, starts, total):
            _polish_close(chain, targets, todo, solved, best_score, (best_q, best_pos, best_rot, best_sing), kw)
    best_sing[~solved] = _rank_lost_at(chain, targets, todo[~solved], best_q[~solved])
    status = np.where(solved, nm.OK, np.where(best_sing, nm.SINGULAR, nm.NOT_CONVERGED))
    return _collect([nm.Solutions(todo, best_q, status, best_pos, best_rot), rejected])


def solve(chain: Chain, targets: nm.Targets, *, all_solutions=False, starts=None, q0=None, seed=0, warm=False,
          table=True, **kw):
    """Numeric IK of a batch; see the module docstring."""
    escalate = ESCALATE_TO if starts is None else None
    if starts is None:
        starts = DEFAULT_STARTS["all" if all_solutions else "first"]
    if all_solutions:
        return solve_all(chain, targets, starts, q0=q0, seed=seed, **kw)
    return solve_first(chain, targets, starts, q0=q0, seed=seed, warm=warm and q0 is not None, table=table,
                       escalate=escalate, **kw)
