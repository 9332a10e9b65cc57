"""Numeric inverse kinematics of any serial arm (:mod:`ik5r.core.chain`), float64, vectorised.

Levenberg-Marquardt on the analytic geometric Jacobian, run on every (pose, start) pair of a batch
at once. Modes: ``pose`` (tool point and full orientation), ``position`` (tool point only),
``direction`` (tool point and tool z axis, the roll about it free, as Park et al.). Each start is a
joint vector drawn uniformly within the limits (start 0 may be given, e.g. the current joints).
The damped step is ``J^T (J J^T + mu I)^-1 e`` or ``(J^T J + mu I)^-1 J^T e``, whichever system is
smaller (they are equal); mu follows Nielsen's rule on the gain ratio (actual over predicted
decrease), so the end game is Gauss-Newton (quadratic).
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

from ik5r.core.chain import Chain, jacobian

MODES = ("pose", "position", "direction")
STATUS_NAMES = ("ok", "not_converged", "singular", "unreachable", "invalid")
OK, NOT_CONVERGED, SINGULAR, UNREACHABLE, INVALID = range(5)
TOL_CM = 1e-9
TOL_RAD = 1e-9
_STOP = 1e-11  # iterate past the tolerance: a margin for FK rounding elsewhere, and --all needs it: at 1e-10
# the joints of an ill-conditioned pose (PUMA near a shoulder singularity) spread over 1e-6, DISTINCT
_CLOSE = 1e-3  # residual (cm, rad) under which a start gets _EXTRA times the iterations
_EXTRA = 8
_HOPELESS = 1.0  # residual (cm, rad) of a start given up after _GIVE_UP steps: on Toz's 6R 95% of
_GIVE_UP = 12  # the random starts that never converge are still that far after 12 steps, and only
# 8% of those that do; a fresh start is cheaper than waiting (Toz 6R: 10.4 against 13.4 us per pose)
_TWO_PI = 2.0 * np.pi
_CHUNK = 32768


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


def rotation_log(Rerr):
    """Rotation vectors (N,3) (axis times angle in [0, pi]) of rotation matrices (N,3,3)."""
    v = 0.5 * np.stack([Rerr[:, 2, 1] - Rerr[:, 1, 2], Rerr[:, 0, 2] - Rerr[:, 2, 0],
                        Rerr[:, 1, 0] - Rerr[:, 0, 1]], axis=1)
    s = np.linalg.norm(v, axis=1)
    c = 0.5 * (np.trace(Rerr, axis1=1, axis2=2) - 1.0)
    angle = np.arctan2(s, c)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = v * np.where(s > 1e-300, angle / s, 1.0)[:, None]
    near_pi = (c < 0) & (s < 1e-6)
    if near_pi.any():  # sin ~ 0: the axis is the largest column of (R + I), sign taken from v
        B = Rerr[near_pi] + np.eye(3)
        col = np.argmax(np.linalg.norm(B, axis=1), axis=1)
        axis = B[np.arange(len(B)), :, col]
        axis /= np.linalg.norm(axis, axis=1)[:, None]
        sign = np.where(np.einsum("ij,ij->i", axis, v[near_pi]) < 0, -1.0, 1.0)
        out[near_pi] = axis * (sign * angle[near_pi])[:, None]
    return out


def _task(targets: Targets, R, p, J, weight):
    """Weighted error e (M,m) and task Jacobian (M,m,n) for the mode."""
    ep = targets.p - p
    if targets.mode == "position":
        return ep, J[:, :3]
    Jw = J[:, 3:]
    if targets.mode == "pose":
        er = rotation_log(targets.R @ np.swapaxes(R, 1, 2))
        Jr = Jw
    else:
        z = R[:, :, 2]
        er = targets.a - z
        Jr = np.cross(np.swapaxes(Jw, 1, 2), z[:, None, :]).swapaxes(1, 2)
    return np.concatenate([ep, weight * er], axis=1), np.concatenate([J[:, :3], weight * Jr], axis=1)


def _step(Jt, e, mu):
    """Damped step (M,n) and g = J^T e (M,n) for absolute damping mu (M,)."""
    m, n = Jt.shape[1:]
    JT = np.swapaxes(Jt, 1, 2)
    g = (JT @ e[:, :, None])[:, :, 0]
    k = min(m, n)
    A = Jt @ JT if m < n else JT @ Jt
    A[:, np.arange(k), np.arange(k)] += mu[:, None]
    if m < n:
        return (JT @ np.linalg.solve(A, e[:, :, None]))[:, :, 0], g
    return np.linalg.solve(A, g[:, :, None])[:, :, 0], g


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


class _Accepted:
    """Per-row state of the accepted iterate (rows shrink as they finish)."""

    def __init__(self, active, q, e, J, pos, rot, mu):
        self.active, self.q, self.e, self.J, self.pos, self.rot, self.mu = active, q, e, J, pos, rot, mu
        self.cost = 0.5 * np.einsum("ij,ij->i", e, e)
        self.nu = np.full(len(q), 2.0)

    def update(self, sel, q, e, J, pos, rot):
        self.q[sel], self.e[sel], self.J[sel], self.pos[sel], self.rot[sel] = q[sel], e[sel], J[sel], pos[sel], rot[sel]
        self.cost[sel] = 0.5 * np.einsum("ij,ij->i", e[sel], e[sel])

    def keep(self, keep):
        for name in ("active", "q", "e", "J", "pos", "rot", "mu", "cost", "nu"):
            setattr(self, name, getattr(self, name)[keep])


def _evaluate(chain, targets, q, weight):
    R, p, J = jacobian(chain, q)
    e, Jt = _task(targets, R, p, J, weight)
    pos, rot = residuals(targets, R, p)
    return e, Jt, pos, rot


def levenberg_marquardt(chain: Chain, targets: Targets, q0, *, iterations=60, tol_cm=TOL_CM,
                        tol_rad=TOL_RAD, polish=True, damping=0.1, give_up=_GIVE_UP):
    """Run LM from q0 (M,n) on targets (M rows), with Nielsen's damping update (gain ratio).
    With ``polish``, starts already within _CLOSE of the target get _EXTRA times the iterations;
    starts farther than _HOPELESS after ``give_up`` steps stop there.
    Returns q, pos_err, rot_err, converged, singular."""
    extra = _EXTRA if polish else 1
    count = len(q0)
    weight = max(chain.reach, 1.0) / 4.0
    out_q = np.array(q0, dtype=np.float64)
    out_pos, out_rot = np.full(count, np.inf), np.full(count, np.inf)
    out_sing = np.zeros(count, dtype=bool)
    e, Jt, pos, rot = _evaluate(chain, targets, out_q, weight)
    diag = np.einsum("ijk,ijk->ik", Jt, Jt)
    st = _Accepted(np.arange(count), out_q.copy(), e, Jt, pos, rot, damping * diag.max(axis=1) + 1e-300)
    tg = targets
    for it in range(extra * iterations + 1):
        within = (st.pos <= tol_cm) & ~(st.rot > tol_rad)
        close = (st.pos <= _CLOSE) & ~(st.rot > _CLOSE)  # crawling along a fold's valley: let it run
        hopeless = (it >= give_up) & ~((st.pos <= _HOPELESS) & ~(st.rot > _HOPELESS))
        done = ((st.pos <= _STOP) & ~(st.rot > _STOP)) | (st.nu > 1e6) | (it >= iterations) & ~close | hopeless
        done |= it == extra * iterations
        done |= within & (st.nu >= 16)  # at the float64 floor: steps keep being rejected
        if done.any():
            idx = st.active[done]
            out_q[idx], out_pos[idx], out_rot[idx] = st.q[done], st.pos[done], st.rot[done]
            failed = done & ~within
            if failed.any():
                out_sing[st.active[failed]] = _rank_lost(st.J[failed])
            st.keep(~done)
            tg = tg.take(~done)
        if not len(st.active):
            break
        h, g = _step(st.J, st.e, st.mu)
        predicted = 0.5 * np.einsum("ij,ij->i", h, st.mu[:, None] * h + g)
        q = clamp(chain, st.q + h)
        e, Jt, pos, rot = _evaluate(chain, tg, q, weight)
        rho = (st.cost - 0.5 * np.einsum("ij,ij->i", e, e)) / np.maximum(predicted, 1e-300)
        accepted = rho > 0
        st.update(accepted, q, e, Jt, pos, rot)
        st.mu = np.where(accepted, st.mu * np.maximum(1 / 3, 1 - (2 * rho - 1) ** 3), st.mu * st.nu)
        st.nu = np.where(accepted, 2.0, st.nu * 2.0)
    converged = (out_pos <= tol_cm) & ~(out_rot > tol_rad)
    return out_q, out_pos, out_rot, converged, out_sing & ~converged


def check_targets(chain: Chain, targets: Targets) -> np.ndarray:
    """Per-pose status before solving: INVALID, UNREACHABLE or OK (to be solved)."""
    status = np.full(len(targets), OK)
    finite = np.isfinite(targets.p).all(axis=1)
    if targets.R is not None:
        with np.errstate(invalid="ignore"):
            finite &= np.isfinite(targets.R).all(axis=(1, 2))
            cols = np.ascontiguousarray(np.moveaxis(targets.R, 2, 0))  # n, o, a: (3, N, 3)
            worst = np.zeros(len(targets))
            for i, j in ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)):  # the Gram matrix less I
                worst = np.fmax(worst, np.abs((cols[i] * cols[j]).sum(axis=1) - (i == j)))
            finite &= worst <= 1e-6
            R = targets.R
            det = np.einsum("ni,ni->n", R[:, :, 0], np.cross(R[:, :, 1], R[:, :, 2]))  # n . (o x a)
            finite &= np.where(np.isfinite(det), det, 0.0) > 0
    if targets.a is not None:
        with np.errstate(invalid="ignore"):
            finite &= np.isfinite(targets.a).all(axis=1) & (np.abs(np.linalg.norm(targets.a, axis=1) - 1) <= 1e-6)
    with np.errstate(invalid="ignore"):
        far = np.linalg.norm(targets.p, axis=1) > chain.reach * (1 + 1e-12) + 1e-9
    status[far] = UNREACHABLE
    status[~finite] = INVALID
    return status
