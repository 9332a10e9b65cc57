"""Float reference of the 5R arm: forward kinematics and closed-form IK with every branch.

Vectorised over batches with numpy; ``dtype`` may be float64 (the reference) or float32 (what a
soft CPU with a single-precision FPU would compute, for the quantisation report).

Geometry (standard DH, see docs/algorithm.md): joint 1 turns the arm's vertical plane about the base
axis; in that plane, with x1 radial and y1 pointing down, joints 2-4 form a planar chain
(a2, a3, a4) and the tool point sits d5 along the approach a = z5. With phi = q2 + q3 + q4:

    r  = a1 + a2 c2 + a3 c23 + a4 c(phi) - d5 s(phi)        p = (r c1, r s1, d1 - y)
    y  =      a2 s2 + a3 s23 + a4 s(phi) + d5 c(phi)        a = (-s(phi) c1, -s(phi) s1, -c(phi))

Branches: bit 1 ``shoulder_back`` (r < 0, q1 = atan2(py, px) + pi), bit 0 ``elbow_down``
(q3 = -acos c3); branch index = 2 * shoulder_back + elbow_down.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import status as st
from .arm import Arm

N_BRANCHES = 4
#: Tool point closer than this to the base axis (cm) counts as on it.
AXIS_TOLERANCE_CM = 1e-9
#: A cosine of q3 beyond 1 by more than this is unreachable rather than rounding noise.
REACH_TOLERANCE = 1e-9


def wrap(angle):
    """Wrap angles to [-pi, pi)."""
    return (angle + np.pi) % (2 * np.pi) - np.pi


def _dh(theta, a, alpha, d, dtype):
    ct, stt = np.cos(theta), np.sin(theta)
    ca, sa = np.cos(alpha), np.sin(alpha)
    t = np.zeros(theta.shape + (4, 4), dtype=dtype)
    t[..., 0, 0], t[..., 0, 1], t[..., 0, 2], t[..., 0, 3] = ct, -stt * ca, stt * sa, a * ct
    t[..., 1, 0], t[..., 1, 1], t[..., 1, 2], t[..., 1, 3] = stt, ct * ca, -ct * sa, a * stt
    t[..., 2, 1], t[..., 2, 2], t[..., 2, 3] = sa, ca, d
    t[..., 3, 3] = 1
    return t


def fk_matrix(arm: Arm, q, dtype=np.float64) -> np.ndarray:
    """Forward kinematics by the product of the five DH matrices: (..., 4, 4) tool poses."""
    q = np.asarray(q, dtype=dtype)
    t = None
    for i in range(5):
        ti = _dh(q[..., i] + arm.theta_offset[i], arm.a[i], arm.alpha[i], arm.d[i], dtype)
        t = ti if t is None else t @ ti
    return t


def fk(arm: Arm, q, dtype=np.float64):
    """Forward kinematics: (p, n, o, a), each (..., 3)."""
    t = fk_matrix(arm, q, dtype)
    return t[..., :3, 3], t[..., :3, 0], t[..., :3, 1], t[..., :3, 2]


@dataclass
class IKResult:
    """Every branch of every pose.

    q: (N, 4, 5) joint angles; status: (N, 4) status bits (0 = ok: reachable, within limits and
    confirmed by FK); residual: (N,) angle (rad) between the given approach and its projection onto
    the arm's plane; q1_free: (N,) True where q1 was free and taken from ``near`` (or 0).
    """

    q: np.ndarray
    status: np.ndarray
    residual: np.ndarray
    q1_free: np.ndarray

    @property
    def valid(self) -> np.ndarray:
        """(N, 4) branches that solve the pose: no bit set but the harmless singular ones."""
        harmless = st.SINGULAR_ELBOW | st.SINGULAR_BASE
        return (self.status & ~harmless) == 0

    def choose(self, near=None) -> np.ndarray:
        """Index of one branch per pose: the valid one nearest ``near`` (sum of squared wrapped
        differences), else the first valid in index order (front shoulder, q3 >= 0 first);
        a pose with no valid branch gets branch 0."""
        valid = self.valid
        if near is None:
            cost = np.broadcast_to(np.arange(N_BRANCHES, dtype=float), valid.shape).copy()
        else:
            cost = np.sum(wrap(self.q - np.asarray(near, dtype=float)) ** 2, axis=-1)
        cost = np.where(valid, cost, np.inf)
        return np.where(valid.any(axis=1), np.argmin(cost, axis=1), 0)


def ik(arm: Arm, p, a, n=None, o=None, near=None, *, singular_sin_q3=1e-3,
       dtype=np.float64, confirm_tolerance_cm=1e-6) -> IKResult:
    """Closed-form IK of N poses, all four branches.

    p, a: (N, 3) tool point (cm) and approach. n, o: (N, 3) or None: then q5 keeps ``near[4]``
    (0 without ``near``). An approach off the arm's plane is projected onto it; ``residual`` reports
    the angle removed. Non-finite input rows get status INVALID.
    """
    p = np.atleast_2d(np.asarray(p, dtype=dtype))
    a = np.atleast_2d(np.asarray(a, dtype=dtype))
    count = p.shape[0]
    near_q = np.zeros(5) if near is None else np.asarray(near, dtype=float)
    rows_bad = ~(np.isfinite(p).all(axis=1) & np.isfinite(a).all(axis=1))
    has_roll = n is not None and o is not None
    if has_roll:
        n = np.atleast_2d(np.asarray(n, dtype=dtype))
        o = np.atleast_2d(np.asarray(o, dtype=dtype))
        rows_bad |= ~(np.isfinite(n).all(axis=1) & np.isfinite(o).all(axis=1))
    with np.errstate(invalid="ignore"):
        p = np.where(rows_bad[:, None], 0, p)
        a = np.where(rows_bad[:, None], 0, a)
    a1, a2, a3, a4, _ = (dtype(v) for v in arm.a)
    d1, d5 = dtype(arm.d[0]), dtype(arm.d[4])
    px, py, pz = p[:, 0], p[:, 1], p[:, 2]
    ax, ay, az = a[:, 0], a[:, 1], a[:, 2]

    base_status = np.where(rows_bad, st.INVALID, 0).astype(np.int64)
    rho = np.hypot(px, py)
    on_axis = rho < AXIS_TOLERANCE_CM
    a_horizontal = np.hypot(ax, ay)
    q1_free = on_axis & (a_horizontal < 1e-12)
    theta1 = np.where(on_axis, np.where(q1_free, near_q[0] + arm.theta_offset[0], np.arctan2(ay, ax)),
                      np.arctan2(py, px)).astype(dtype)
    base_status |= np.where(q1_free, st.SINGULAR_BASE, 0)

    q = np.empty((count, N_BRANCHES, 5), dtype=dtype)
    status = np.empty((count, N_BRANCHES), dtype=np.int64)
    residual = np.zeros(count, dtype=dtype)
    for shoulder_back in (0, 1):
        q1 = wrap(theta1 + np.pi) if shoulder_back else theta1
        r = -rho if shoulder_back else rho
        c1, s1 = np.cos(q1), np.sin(q1)
        a_radial = ax * c1 + ay * s1
        a_normal = -ax * s1 + ay * c1
        a_in_plane = np.hypot(a_radial, az)
        if not shoulder_back:
            residual = np.arctan2(np.abs(a_normal), a_in_plane)
        no_direction = a_in_plane < 1e-12
        phi = np.arctan2(-a_radial, -az)
        cphi, sphi = np.cos(phi), np.sin(phi)
        xw = r - a1 - (a4 * cphi - d5 * sphi)
        yw = d1 - pz - (a4 * sphi + d5 * cphi)
        c3 = (xw * xw + yw * yw - a2 * a2 - a3 * a3) / (2 * a2 * a3)
        unreachable = np.abs(c3) > 1 + REACH_TOLERANCE
        c3 = np.clip(c3, -1, 1)
        s3_abs = np.sqrt((1 - c3) * (1 + c3))
        elbow = np.arctan2(s3_abs, c3)
        gamma = np.arctan2(yw, xw)
        beta = np.arctan2(a3 * s3_abs, a2 + a3 * c3)
        if has_roll:
            q5 = np.arctan2(n[:, 0] * s1 - n[:, 1] * c1, o[:, 0] * s1 - o[:, 1] * c1)
        else:
            q5 = np.full(count, near_q[4] + arm.theta_offset[4], dtype=dtype)
        common = (base_status | np.where(unreachable, st.UNREACHABLE, 0)
                  | np.where(s3_abs <= singular_sin_q3, st.SINGULAR_ELBOW, 0)
                  | np.where(no_direction, st.INVALID, 0))
        for elbow_down in (0, 1):
            b = 2 * shoulder_back + elbow_down
            q3 = -elbow if elbow_down else elbow
            q2 = wrap(gamma + beta if elbow_down else gamma - beta)
            q4 = wrap(phi - q2 - q3)
            theta = np.stack([q1, q2, q3, q4, q5], axis=-1)
            q[:, b] = wrap(theta - np.asarray(arm.theta_offset, dtype=dtype))
            status[:, b] = common
    within = np.all((q >= arm.lower - 1e-12) & (q <= arm.upper + 1e-12), axis=-1)
    status |= np.where(within, 0, st.OUT_OF_LIMITS)
    if confirm_tolerance_cm is not None:
        # FK round trip of every branch: the tool point must come back (cheap planar closed form).
        p_back = _tool_point(arm, q.astype(np.float64))
        miss = np.linalg.norm(p_back - p[:, None, :].astype(np.float64), axis=-1) > confirm_tolerance_cm
        status |= np.where(miss & (status == 0) | (miss & (status == st.SINGULAR_ELBOW)), st.UNREACHABLE, 0)
    return IKResult(q, status, residual, q1_free)


def _tool_point(arm: Arm, q) -> np.ndarray:
    """Tool point of joint vectors q (..., 5) by the planar closed form (matches fk)."""
    t = q + np.asarray(arm.theta_offset)
    a1, a2, a3, a4, _ = arm.a
    c2, s2 = np.cos(t[..., 1]), np.sin(t[..., 1])
    t23 = t[..., 1] + t[..., 2]
    phi = t23 + t[..., 3]
    r = a1 + a2 * c2 + a3 * np.cos(t23) + a4 * np.cos(phi) - arm.d[4] * np.sin(phi)
    y = a2 * s2 + a3 * np.sin(t23) + a4 * np.sin(phi) + arm.d[4] * np.cos(phi)
    return np.stack([r * np.cos(t[..., 0]), r * np.sin(t[..., 0]), arm.d[0] - y], axis=-1)


def random_joints(arm: Arm, count: int, rng: np.random.Generator) -> np.ndarray:
    """Joint vectors uniform within the arm's limits."""
    return rng.uniform(arm.lower, arm.upper, size=(count, 5))
