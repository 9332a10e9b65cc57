"""Numeric inverse kinematics of any serial arm (:mod:`ik5r.chain`), float64, vectorised.

Levenberg-Marquardt on the analytic geometric Jacobian, run on every (pose, start) pair of a batch
at once. Modes: ``pose`` (tool point and full orientation), ``position`` (tool point only),
``direction`` (tool point and tool z axis, the roll about it free, as Park et al.). Each start is a
joint vector drawn uniformly within the limits (start 0 may be given, e.g. the current joints).
The damped step is ``J^T (J J^T + lam I)^-1 e`` or ``(J^T J + lam I)^-1 J^T e``, whichever system is
smaller (they are equal), with lam relative to the trace of J^T J, divided by 10 after an accepted
step and multiplied by 10 after a rejected one, so the end game is Gauss-Newton (quadratic).
Joints whose limits span a full turn are wrapped into them; the others are clipped.

Statuses (per output row): ``ok`` (both residuals within tolerance), ``invalid`` (a non-finite
input, or n/o/a not orthonormal within 1e-6), ``unreachable`` (tool point farther from the base
than the arm's reach bound: no solution exists), ``singular`` (no start converged; the best one
ended where the task Jacobian has lost rank, sigma_min < 1e-7 sigma_max), ``not_converged``
(no start converged otherwise). Residuals: position in cm, orientation in rad (angle between
target and reached frame in pose mode, between the z axes in direction mode, NaN in position mode).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .chain import Chain, jacobian

MODES = ("pose", "position", "direction")
STATUS_NAMES = ("ok", "not_converged", "singular", "unreachable", "invalid")
OK, NOT_CONVERGED, SINGULAR, UNREACHABLE, INVALID = range(5)
TOL_CM = 1e-9
TOL_RAD = 1e-9
_STOP = 1e-11  # iterate past the tolerance: one more Newton step is nearly free and exact
_TWO_PI = 2.0 * np.pi
_CHUNK = 8192


@dataclass
class Targets:
    """Poses to solve: tool points p (N,3) cm, and R (N,3,3) columns n,o,a (pose) or a (N,3)."""

    mode: str
    p: np.ndarray
    R: np.ndarray | None = None
    a: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.p)

    def take(self, idx) -> "Targets":
        return Targets(self.mode, self.p[idx], None if self.R is None else self.R[idx],
                       None if self.a is None else self.a[idx])


@dataclass
class Solutions:
    """Output rows: pose index, joints (M, n), status code, residuals (cm, rad)."""

    row: np.ndarray
    q: np.ndarray
    status: np.ndarray
    pos_err: np.ndarray
    rot_err: np.ndarray

    def counts(self, poses: int) -> np.ndarray:
        """Number of ok solutions of each pose."""
        return np.bincount(self.row[self.status == OK], minlength=poses)


def _chord_angle(chord):
    """Angle whose unit vectors / rotations are ``chord`` apart (precise near 0)."""
    return 2.0 * np.arcsin(np.minimum(chord / 2.0, 1.0))


def residuals(targets: Targets, R, p):
    """Position error (cm) and orientation error (rad; NaN in position mode) of reached R, p."""
    pos = np.linalg.norm(targets.p - p, axis=1)
    if targets.mode == "pose":
        rot = _chord_angle(np.linalg.norm(R - targets.R, axis=(1, 2)) / np.sqrt(2.0))
    elif targets.mode == "direction":
        rot = _chord_angle(np.linalg.norm(R[:, :, 2] - targets.a, axis=1))
    else:
        rot = np.full(len(p), np.nan)
    return pos, rot


def _task(targets: Targets, R, p, J, weight):
    """Weighted error e (M,m) and task Jacobian (M,m,n) for the mode."""
    ep = targets.p - p
    if targets.mode == "position":
        return ep, J[:, :3]
    Jw = J[:, 3:]
    if targets.mode == "pose":
        er = 0.5 * sum(np.cross(R[:, :, k], targets.R[:, :, k]) for k in range(3))
        Jr = Jw
    else:
        z = R[:, :, 2]
        er = targets.a - z
        Jr = np.cross(np.swapaxes(Jw, 1, 2), z[:, None, :]).swapaxes(1, 2)
    return np.concatenate([ep, weight * er], axis=1), np.concatenate([J[:, :3], weight * Jr], axis=1)


def _step(Jt, e, lam):
    m, n = Jt.shape[1:]
    JT = np.swapaxes(Jt, 1, 2)
    if m < n:
        A = Jt @ JT
        damp = lam * np.trace(A, axis1=1, axis2=2) / m
        A[:, np.arange(m), np.arange(m)] += damp[:, None] + 1e-300
        return (JT @ np.linalg.solve(A, e[:, :, None]))[:, :, 0]
    A = JT @ Jt
    damp = lam * np.trace(A, axis1=1, axis2=2) / n
    A[:, np.arange(n), np.arange(n)] += damp[:, None] + 1e-300
    return np.linalg.solve(A, (JT @ e[:, :, None]))[:, :, 0]


def clamp(chain: Chain, q):
    """Wrap full-turn revolute joints into their limits, clip the others."""
    wraps = chain.wraps()
    lo, hi = chain.lower, chain.upper
    out = np.clip(q, lo, hi)
    if wraps.any():
        out[:, wraps] = lo[wraps] + np.mod(q[:, wraps] - lo[wraps], _TWO_PI)
    return out


def _rank_lost(Jt) -> np.ndarray:
    s = np.linalg.svd(Jt, compute_uv=False)
    return s[:, -1] < 1e-7 * s[:, 0]


def levenberg_marquardt(chain: Chain, targets: Targets, q0, *, iterations=60, tol_cm=TOL_CM,
                        tol_rad=TOL_RAD):
    """Run LM from q0 (M,n) on targets (M rows). Returns q, pos_err, rot_err, converged, singular."""
    count = len(q0)
    weight = max(chain.reach, 1.0) / 4.0
    q_out = np.array(q0, dtype=np.float64)
    pos_out = np.full(count, np.inf)
    rot_out = np.full(count, np.inf)
    sing_out = np.zeros(count, dtype=bool)
    active = np.arange(count)
    q = q_out.copy()
    qa = q.copy()
    cost_a = np.full(count, np.inf)
    lam = np.full(count, 1e-3)
    ea = Ja = None
    tg = targets
    for _ in range(iterations):
        R, p, J = jacobian(chain, q)
        e, Jt = _task(tg, R, p, J, weight)
        cost = np.einsum("ij,ij->i", e, e)
        better = cost < cost_a
        qa[better], cost_a[better] = q[better], cost[better]
        pos, rot = residuals(tg, R, p)
        if ea is None:
            ea, Ja, pos_a, rot_a = e, Jt, pos, rot
        else:
            ea[better], Ja[better], pos_a[better], rot_a[better] = e[better], Jt[better], pos[better], rot[better]
        lam = np.where(better, np.maximum(lam * 0.1, 1e-16), lam * 10.0)
        done = ((pos_a <= _STOP) & ~(rot_a > _STOP)) | (lam > 1e8)
        done |= ~better & (pos_a <= tol_cm) & ~(rot_a > tol_rad)
        if done.any():
            idx = active[done]
            q_out[idx], pos_out[idx], rot_out[idx] = qa[done], pos_a[done], rot_a[done]
            failed = done & ~((pos_a <= tol_cm) & ~(rot_a > tol_rad))
            if failed.any():
                sing_out[active[failed]] = _rank_lost(Ja[failed])
            keep = ~done
            active, qa, cost_a, lam = active[keep], qa[keep], cost_a[keep], lam[keep]
            ea, Ja, pos_a, rot_a = ea[keep], Ja[keep], pos_a[keep], rot_a[keep]
            tg = tg.take(keep)
        if not len(active):
            break
        q = clamp(chain, qa + _step(Ja, ea, lam))
    if len(active):
        q_out[active], pos_out[active], rot_out[active] = qa, pos_a, rot_a
        sing_out[active] = _rank_lost(Ja)
    converged = (pos_out <= tol_cm) & ~(rot_out > tol_rad)
    return q_out, pos_out, rot_out, converged, sing_out & ~converged


def check_targets(chain: Chain, targets: Targets) -> np.ndarray:
    """Per-pose status before solving: INVALID, UNREACHABLE or OK (to be solved)."""
    status = np.full(len(targets), OK)
    finite = np.isfinite(targets.p).all(axis=1)
    if targets.R is not None:
        with np.errstate(invalid="ignore"):
            finite &= np.isfinite(targets.R).all(axis=(1, 2))
            gram = np.swapaxes(targets.R, 1, 2) @ targets.R
            finite &= np.abs(gram - np.eye(3)).max(axis=(1, 2)) <= 1e-6
            finite &= np.linalg.det(np.where(np.isfinite(targets.R), targets.R, 0.0)) > 0
    if targets.a is not None:
        with np.errstate(invalid="ignore"):
            finite &= np.isfinite(targets.a).all(axis=1) & (np.abs(np.linalg.norm(targets.a, axis=1) - 1) <= 1e-6)
    with np.errstate(invalid="ignore"):
        far = np.linalg.norm(targets.p, axis=1) > chain.reach * (1 + 1e-12) + 1e-9
    status[far] = UNREACHABLE
    status[~finite] = INVALID
    return status
