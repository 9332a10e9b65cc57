"""Float reference of the 5R arm: forward kinematics and closed-form IK with every branch.

Vectorised over batches with numpy; ``dtype`` may be float64 (the reference) or float32 (what a
soft CPU with a single-precision FPU would compute, for the quantisation report).

Geometry (standard DH, see docs/algorithm.md): joint 1 turns the arm's vertical plane about the base
axis; in that plane, with x1 radial and y1 pointing down, joints 2-4 form a planar chain
(a2, a3, a4) and the tool point sits d5 along the approach a = z5. With phi = q2 + q3 + q4
(joint angles here include the arm's ``theta_offset``):

    r  = a1 + a2 c2 + a3 c23 + a4 c(phi) - d5 s(phi)        p = (r c1, r s1, d1 - y)
    y  =      a2 s2 + a3 s23 + a4 s(phi) + d5 c(phi)        a = (-s(phi) c1, -s(phi) s1, -c(phi))
    n  = (c1 c(phi) c5 + s1 s5, s1 c(phi) c5 - c1 s5, -s(phi) c5)
    o  = (-c1 c(phi) s5 + s1 c5, -s1 c(phi) s5 - c1 c5, s(phi) s5)

Branches: bit 1 ``shoulder_back`` (r < 0, q1 = atan2(py, px) + pi), bit 0 ``elbow_down``
(q3 = -acos c3); branch index = 2 * shoulder_back + elbow_down:

    0  shoulder front, elbow up   (q3 >= 0)      <- the default choice when it is valid
    1  shoulder front, elbow down (q3 <= 0)
    2  shoulder back,  elbow up
    3  shoulder back,  elbow down

**Default branch** (:meth:`IKResult.choose` without ``near``): the first *valid* branch in index
order, i.e. front shoulder / elbow up first, then front / elbow down, back / up, back / down.
With ``near``: the valid branch nearest ``near`` (sum of squared wrapped joint differences).

Special cases, per pose:

* tool point on the base axis (rho < ``AXIS_TOLERANCE_CM``): the arm's plane is the plane of the
  approach, q1 = atan2(ay, ax); if the approach is also vertical, q1 is free: it takes ``near[0]``
  (0 without ``near``; the back shoulder near[0] + pi), status SINGULAR_BASE, ``q1_free`` True.
* approach off the arm's plane: projected onto it; ``residual`` is the angle removed (rad).
  An approach with no component in the plane (perpendicular to it, or zero) is INVALID.
* position + tool direction only (``n``, ``o`` absent): q5 = ``near[4]`` (0 without ``near``).
* non-finite input, or a value beyond ``input_limit(dtype)`` (its square would overflow): the row
  is INVALID, its q NaN; the other rows are solved as usual.
* approach off the arm's plane by more than ``orientation_tolerance`` (sine of the angle, relative
  to |a|), or n, o, a not a right-handed orthonormal frame (|n.n - 1|, |o.o - 1|, |n.o|, a
  component of n x o - a above it): BAD_ORIENTATION on every branch (the joints solve the
  projected approach).
* |c3| > 1 + reach_tolerance: UNREACHABLE, the elbow is clipped straight or folded (the arm
  points at the target); |sin q3| <= singular_sin_q3: SINGULAR_ELBOW (still a valid solution).
* joint limits of the arm filter branches (OUT_OF_LIMITS); an angle is reported in [-pi, pi] or,
  where a limit extends beyond +-pi and only that puts it within the limits, shifted by 2 pi.

Every branch is confirmed by an FK round trip: the returned angles go through the forward
kinematics (trigonometry of the returned q, nothing reused from the solve) and the tool point must
come back within ``confirm_tolerance_cm`` and the (projected) approach within ``confirm_tolerance_dir``;
a branch that fails, and was otherwise valid, is marked UNREACHABLE. q5 is read off n and o directly
(q5 = atan2(n . e, o . e), e = (s1, -c1, 0)) and does not affect the tool point or the approach.

Angles are returned in [-pi, pi] (atan2's range), except for the limit shift above.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import status as st
from .arm import Arm

N_BRANCHES = 4
#: Branch names by index (2 * shoulder_back + elbow_down).
BRANCH_NAMES = ("front_up", "front_down", "back_up", "back_down")
#: Tool point closer than this to the base axis (cm) counts as on it.
AXIS_TOLERANCE_CM = 1e-9
#: A cosine of q3 beyond 1 by more than this is unreachable rather than rounding noise.
REACH_TOLERANCE = 1e-9
#: A direction component below this fraction of the vector's length counts as zero.
DIRECTION_TOLERANCE = 1e-12
#: Off-plane approach (sine of its angle to the arm's plane) or n, o, a frame error above this:
#: BAD_ORIENTATION (see :mod:`ik5r.status`).
ORIENTATION_TOLERANCE = 1e-3

#: Default FK round-trip tolerances per dtype: (tool point, cm; approach, unit vector).
CONFIRM_TOLERANCE = {np.float64: (1e-6, 1e-9), np.float32: (1e-2, 1e-4)}

_TWO_PI = 2.0 * np.pi


def wrap(angle):
    """Wrap angles to [-pi, pi)."""
    return (angle + np.pi) % (2 * np.pi) - np.pi


def branch_bits(branch):
    """(shoulder_back, elbow_down) bools of branch indices."""
    branch = np.asarray(branch)
    return (branch & 2) != 0, (branch & 1) != 0


# --------------------------------------------------------------------------------------------
# Forward kinematics
# --------------------------------------------------------------------------------------------

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
    """Forward kinematics in closed form (see the module docstring): (p, n, o, a), each (..., 3).

    Equal to :func:`fk_matrix` (the product of the DH matrices) to rounding, and much faster.
    """
    q = np.asarray(q, dtype=dtype)
    t = q + np.asarray(arm.theta_offset, dtype=dtype)
    a1, a2, a3, a4, _ = arm.a
    d1, d5 = arm.d[0], arm.d[4]
    c1, s1 = np.cos(t[..., 0]), np.sin(t[..., 0])
    t23 = t[..., 1] + t[..., 2]
    phi = t23 + t[..., 3]
    c2, s2 = np.cos(t[..., 1]), np.sin(t[..., 1])
    c23, s23 = np.cos(t23), np.sin(t23)
    cp, sp = np.cos(phi), np.sin(phi)
    c5, s5 = np.cos(t[..., 4]), np.sin(t[..., 4])
    r = a1 + a2 * c2 + a3 * c23 + a4 * cp - d5 * sp
    y = a2 * s2 + a3 * s23 + a4 * sp + d5 * cp
    p = np.stack([r * c1, r * s1, d1 - y], axis=-1)
    n = np.stack([c1 * cp * c5 + s1 * s5, s1 * cp * c5 - c1 * s5, -sp * c5], axis=-1)
    o = np.stack([-c1 * cp * s5 + s1 * c5, -s1 * cp * s5 - c1 * c5, sp * s5], axis=-1)
    a = np.stack([-sp * c1, -sp * s1, -cp], axis=-1)
    return p, n, o, a


#: Column names of a pose row as :func:`fk_pose` lays it out (and ``ik5r fk`` writes it).
POSE_COLUMNS = ("px", "py", "pz", "nx", "ny", "nz", "ox", "oy", "oz", "ax", "ay", "az")


def fk_pose(arm: Arm, q, dtype=np.float64) -> np.ndarray:
    """Forward kinematics as (..., 12) rows in :data:`POSE_COLUMNS` order (p, n, o, a)."""
    return np.concatenate(fk(arm, q, dtype), axis=-1)


def _tool_point(arm: Arm, q) -> np.ndarray:
    """Tool point of joint vectors q (..., 5) by the planar closed form (matches fk)."""
    return fk(arm, q)[0]


def random_joints(arm: Arm, count: int, rng: np.random.Generator) -> np.ndarray:
    """Joint vectors uniform within the arm's limits."""
    return rng.uniform(arm.lower, arm.upper, size=(count, 5))


# --------------------------------------------------------------------------------------------
# Inverse kinematics
# --------------------------------------------------------------------------------------------

@dataclass
class IKResult:
    """Every branch of every pose.

    q: (N, 4, 5) joint angles (a view; NaN on INVALID rows); status: (N, 4) status bits (0 = ok:
    reachable, within limits and confirmed by FK; exactly INVALID on invalid rows); residual: (N,)
    angle (rad) between the given approach and its projection onto the arm's plane (NaN for
    non-finite input); q1_free: (N,) True where q1 was free
    (SINGULAR_BASE) and taken from ``near`` (or 0): the chosen value is ``q[:, 0, 0]``.
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

    @property
    def any_valid(self) -> np.ndarray:
        """(N,) poses with at least one valid branch."""
        return self.valid.any(axis=1)

    def choose(self, near=None) -> np.ndarray:
        """Index of one branch per pose: the valid one nearest ``near`` (sum of squared wrapped
        differences; ``near`` (5,) or (N, 5)), else the first valid in index order (front shoulder,
        q3 >= 0 first); a pose with no valid branch gets branch 0. A pose with BAD_ORIENTATION
        (all its branches) is chosen among as if it were not set."""
        valid = self.valid
        # BAD_ORIENTATION is a property of the pose: among its branches, choose as if it were not set.
        usable = (self.status & ~(st.SINGULAR_ELBOW | st.SINGULAR_BASE | st.BAD_ORIENTATION)) == 0
        valid = np.where(valid.any(axis=1, keepdims=True), valid, usable)
        if near is None:
            cost = np.broadcast_to(np.arange(N_BRANCHES, dtype=float), valid.shape).copy()
        else:
            near = np.asarray(near, dtype=float)
            if near.ndim == 2:
                near = near[:, None, :]
            with np.errstate(invalid="ignore"):
                cost = np.sum(wrap(self.q - near) ** 2, axis=-1)
        cost = np.where(valid, cost, np.inf)
        return np.where(valid.any(axis=1), np.argmin(cost, axis=1), 0)

    def best(self, near=None):
        """(q (N, 5), status (N,), branch (N,)) of the chosen branch of every pose."""
        branch = self.choose(near)
        rows = np.arange(len(branch))
        return self.q[rows, branch], self.status[rows, branch], branch


def _rows(x, dtype, name):
    """(N, 3) input as an array of ``dtype`` (no copy when it already is one)."""
    x = np.asarray(x, dtype=dtype)
    if x.ndim == 1:
        x = x[None, :]
    if x.ndim != 2 or x.shape[1] != 3:
        raise ValueError(f"{name} must have shape (N, 3), got {x.shape}")
    return x


#: Poses solved per pass: the temporaries of a pass stay in the CPU cache.
CHUNK = 16384


def input_limit(dtype) -> float:
    """Largest |input value| the IK takes in ``dtype``: squares and their sums stay finite."""
    return float(np.sqrt(np.finfo(dtype).max) / 16)


def frame_error(n, o, a):
    """(3, m) n, o, a -> (m,) largest of |n.n - 1|, |o.o - 1|, |n.o| and |n x o - a| (per component)."""
    nn = np.einsum("im,im->m", n, n) - 1
    oo = np.einsum("im,im->m", o, o) - 1
    no = np.einsum("im,im->m", n, o)
    cross = np.cross(n, o, axis=0) - a
    return np.max(np.abs(np.vstack([nn, oo, no, cross])), axis=0)


def ik(arm: Arm, p, a, n=None, o=None, near=None, *, singular_sin_q3=1e-3,
       reach_tolerance=REACH_TOLERANCE, orientation_tolerance=ORIENTATION_TOLERANCE,
       dtype=np.float64, confirm_tolerance_cm="auto", confirm_tolerance_dir="auto") -> IKResult:
    """Closed-form IK of N poses, all four branches (see the module docstring).

    p, a: (N, 3) tool point (cm) and approach (any length). n, o: (N, 3) or None (both or
    neither): then q5 keeps ``near[4]`` (0 without ``near``). ``near``: (5,) or (N, 5) joint
    vector that a free q1 and an unspecified q5 take (the choice of branch is
    :meth:`IKResult.choose`). The FK round trip tolerances default ("auto") to
    :data:`CONFIRM_TOLERANCE` of the dtype; ``confirm_tolerance_cm=None`` skips the round trip.
    """
    dt = np.dtype(dtype)
    p = _rows(p, dt, "p")
    a = _rows(a, dt, "a")
    count = p.shape[0]
    if a.shape[0] != count:
        raise ValueError("p and a must have the same number of rows")
    if (n is None) != (o is None):
        raise ValueError("give both n and o, or neither")
    if n is not None:
        n, o = _rows(n, dt, "n"), _rows(o, dt, "o")
        if n.shape[0] != count or o.shape[0] != count:
            raise ValueError("n and o must have as many rows as p")
    near_q = np.zeros(5) if near is None else np.asarray(near, dtype=np.float64)
    if near_q.shape not in ((5,), (count, 5)):
        raise ValueError(f"near must have shape (5,) or (N, 5), got {near_q.shape}")
    if confirm_tolerance_cm is None:
        tolerances = None
    else:
        auto_cm, auto_dir = CONFIRM_TOLERANCE.get(dt.type, CONFIRM_TOLERANCE[np.float64])
        tolerances = (auto_cm if isinstance(confirm_tolerance_cm, str) else float(confirm_tolerance_cm),
                      auto_dir if isinstance(confirm_tolerance_dir, str) else float(confirm_tolerance_dir))
    Q = np.empty((N_BRANCHES, 5, count), dtype=dt)      # exposed as the (N, 4, 5) view
    S = np.empty((N_BRANCHES, count), dtype=np.int64)
    residual = np.empty(count, dtype=dt)
    q1_free = np.zeros(count, dtype=bool)
    kernel = _Kernel(arm, dt, singular_sin_q3, tolerances, reach_tolerance, orientation_tolerance)
    for lo in range(0, count, CHUNK):
        sl = slice(lo, min(count, lo + CHUNK))
        near_c = near_q if near_q.ndim == 1 else near_q[sl]
        kernel.solve(p[sl], a[sl], None if n is None else n[sl], None if o is None else o[sl],
                     near_c[..., 0], near_c[..., 4], Q[:, :, sl], S[:, sl], residual[sl], q1_free[sl])
    return IKResult(Q.transpose(2, 0, 1), S.T, residual, q1_free)


class _Kernel:
    """The closed-form IK of one chunk of poses, written into slices of the result arrays."""

    def __init__(self, arm: Arm, dt, singular_sin_q3, tolerances, reach_tolerance, orientation_tolerance):
        self.arm, self.dt, self.singular = arm, dt, float(singular_sin_q3)
        self.reach, self.orientation = float(reach_tolerance), float(orientation_tolerance)
        self.tolerances = tolerances
        self.offsets = np.asarray(arm.theta_offset, dtype=np.float64)
        self.has_offset = bool(np.any(self.offsets != 0))
        # joints whose limits do not contain all of [-pi, pi]: (j, lo, hi)
        self.limited = [(j, lo, hi) for j, (lo, hi) in enumerate(arm.limits)
                        if not (lo <= -np.pi and hi >= np.pi)]

    def solve(self, p, a, n, o, near0, near4, Q, S, residual, q1_free):
        arm, dt = self.arm, self.dt
        offsets = self.offsets
        has_roll = n is not None
        count = p.shape[0]
        a1, a2, a3, a4, _ = arm.a
        d1, d5 = arm.d[0], arm.d[4]
        P = np.array(p.T, dtype=dt, order="C")      # private (3, chunk) copies
        A = np.array(a.T, dtype=dt, order="C")
        # ---- input validity: non-finite rows are solved as placeholders and flagged INVALID ----
        finite = np.isfinite(P).all(axis=0) & np.isfinite(A).all(axis=0)
        if has_roll:
            Nv = np.array(n.T, dtype=dt, order="C")
            Ov = np.array(o.T, dtype=dt, order="C")
            finite &= np.isfinite(Nv).all(axis=0) & np.isfinite(Ov).all(axis=0)
        limit = input_limit(dt)
        with np.errstate(invalid="ignore"):
            for values in (P, A) + ((Nv, Ov) if has_roll else ()):
                finite &= (np.abs(values) <= limit).all(axis=0)
        bad = ~finite
        any_bad = bool(bad.any())
        if any_bad:
            P[:, bad] = 0
            A[:, bad] = 1
            if has_roll:
                Nv[:, bad] = 1
                Ov[:, bad] = 1
        px, py, pz = P
        ax, ay, az = A

        # ---- joint 1: the arm's plane, its cos/sin without trigonometry ----
        rho = px * px
        rho += py * py
        np.sqrt(rho, out=rho)
        with np.errstate(invalid="ignore", divide="ignore"):
            inv_rho = np.reciprocal(rho)
            c1 = px * inv_rho                  # fixed below where the point is on the axis
            s1 = py * inv_rho
        theta1 = np.arctan2(py, px)
        on_axis = np.flatnonzero(rho < AXIS_TOLERANCE_CM)
        if on_axis.size:
            axo, ayo, azo = ax[on_axis], ay[on_axis], az[on_axis]
            horizontal = np.hypot(axo, ayo)
            free = horizontal <= DIRECTION_TOLERANCE * np.sqrt(axo * axo + ayo * ayo + azo * azo)
            free |= horizontal == 0
            if any_bad:
                free &= finite[on_axis]
            q1_free[on_axis] = free
            with np.errstate(invalid="ignore", divide="ignore"):
                c1[on_axis] = np.where(free, 0, axo / horizontal)
                s1[on_axis] = np.where(free, 0, ayo / horizontal)
            theta1[on_axis] = np.arctan2(ayo, axo)
            idx = on_axis[free]
            if idx.size:
                t = _wrap_scalar(np.broadcast_to(near0, (count,))[idx] + offsets[0])
                theta1[idx] = t
                c1[idx] = np.cos(t)
                s1[idx] = np.sin(t)

        # ---- approach: projection onto the arm's plane (front-shoulder frame) ----
        a_rad = ax * c1
        a_rad += ay * s1
        a_nrm = ay * c1
        a_nrm -= ax * s1
        a_in = a_rad * a_rad
        a_in += az * az
        a_len2 = a_nrm * a_nrm
        a_len2 += a_in
        np.sqrt(a_in, out=a_in)
        np.abs(a_nrm, out=a_nrm)
        np.arctan2(a_nrm, a_in, out=residual)
        np.sqrt(a_len2, out=a_len2)
        bad_orientation = a_nrm > a_len2 * self.orientation
        if has_roll:
            bad_orientation |= frame_error(Nv, Ov, A) > self.orientation
        no_direction = a_in <= a_len2 * DIRECTION_TOLERANCE
        no_direction |= a_in == 0
        if no_direction.any():
            a_in[no_direction] = 1.0
        inv_in = np.reciprocal(a_in)
        # phi (front) = atan2(-a_rad, -az); back shoulder: phi_b = -phi, cos equal, sin negated.
        cphi = az * inv_in
        np.negative(cphi, out=cphi)
        sphi = a_rad * inv_in            # = -sin(phi_front) = sin(phi_back)
        phi_f = np.arctan2(-a_rad, -az)

        # ---- joint 5 ----
        if has_roll:
            nx, ny, _ = Nv
            ox, oy, _ = Ov
            s5 = nx * s1
            s5 -= ny * c1
            c5 = ox * s1
            c5 -= oy * c1
            q5_f = np.arctan2(s5, c5)
            np.abs(s5, out=s5)
            np.abs(c5, out=c5)
            s5 += c5
            scale = np.abs(nx)
            scale += np.abs(ny)
            scale += np.abs(ox)
            scale += np.abs(oy)
            scale *= DIRECTION_TOLERANCE
            no_roll = s5 <= scale
            no_roll |= s5 == 0
            q5_b = _opposite(q5_f)
            invalid_rows = no_direction | no_roll
        else:
            q5_f = np.broadcast_to(np.asarray(_wrap_scalar(near4 + offsets[4]), dtype=dt), (count,))
            q5_b = q5_f
            invalid_rows = no_direction
        if any_bad:
            invalid_rows |= bad

        # ---- base status ----
        base = np.zeros(count, dtype=np.int64)
        base[invalid_rows] = st.INVALID
        base[q1_free] |= st.SINGULAR_BASE
        base[bad_orientation] |= st.BAD_ORIENTATION

        q1_b = _opposite(theta1)
        l_sq = a2 * a2 + a3 * a3
        inv_2l = 1.0 / (2.0 * a2 * a3)
        zmp = d1 - pz
        for back in (0, 1):
            # wrist centre (joint 4 axis) in the arm's plane
            if back:
                off_x = a4 * cphi
                off_x -= d5 * sphi         # a4 c(phi_b) - d5 s(phi_b)
                off_y = a4 * sphi
                xw = -rho
            else:
                off_x = d5 * sphi
                off_x += a4 * cphi
                off_y = -a4 * sphi
                xw = rho.copy()
            off_y += d5 * cphi
            xw -= a1
            xw -= off_x
            yw = zmp - off_y
            c3 = xw * xw
            c3 += yw * yw
            c3 -= l_sq
            c3 *= inv_2l
            status = base.copy()
            status[np.abs(c3) > 1 + self.reach] |= st.UNREACHABLE
            np.minimum(c3, 1.0, out=c3)
            np.maximum(c3, -1.0, out=c3)
            s3 = 1.0 - c3
            s3 *= 1.0 + c3
            np.sqrt(s3, out=s3)
            status[s3 <= self.singular] |= st.SINGULAR_ELBOW
            # q2 = atan2(yw, xw) -+ atan2(a3 s3, a2 + a3 c3), as one atan2 of a complex product
            k1 = a3 * c3
            k1 += a2
            k2 = a3 * s3
            u = xw * k1
            v = yw * k2
            w = yw * k1
            z = xw * k2
            phi = -phi_f if back else phi_f
            q1 = q1_b if back else theta1
            q5 = q5_b if back else q5_f
            for down in (0, 1):
                b = 2 * back + down
                qb = Q[b]
                qb[0] = q1
                if down:
                    np.arctan2(w + z, u - v, out=qb[1])
                    np.arctan2(s3, c3, out=qb[2])
                    np.negative(qb[2], out=qb[2])
                else:
                    np.arctan2(w - z, u + v, out=qb[1])
                    np.arctan2(s3, c3, out=qb[2])
                q4 = qb[3]
                np.subtract(phi, qb[1], out=q4)
                q4 -= qb[2]
                _wrap_inplace(q4)
                qb[4] = q5
                S[b] = status
        if self.has_offset:
            for j in range(5):
                if offsets[j] != 0:
                    Q[:, j] -= offsets[j]
                    _wrap_inplace(Q[:, j])

        # ---- joint limits ----
        for j, lo, hi in self.limited:
            qj = Q[:, j]
            if hi > np.pi:   # the representative above pi may be the one within the limits
                shift = (qj < lo - 1e-12) & (qj + _TWO_PI <= hi + 1e-12)
                qj[shift] += _TWO_PI
            if lo < -np.pi:
                shift = (qj > hi + 1e-12) & (qj - _TWO_PI >= lo - 1e-12)
                qj[shift] -= _TWO_PI
            S[(qj < lo - 1e-12) | (qj > hi + 1e-12)] |= st.OUT_OF_LIMITS

        # ---- FK round trip of every branch ----
        if self.tolerances is not None:
            _confirm(arm, Q, S, P, cphi, sphi, c1, s1, offsets, *self.tolerances)
        if invalid_rows.any():
            Q[:, :, invalid_rows] = np.nan
            S[:, invalid_rows] = st.INVALID
        if any_bad:
            residual[bad] = np.nan


def _opposite(angle):
    """The angle + pi brought back to [-pi, pi] (atan2 of the opposite vector)."""
    out = angle - np.pi
    out[angle <= 0] += _TWO_PI
    return out


def _wrap_scalar(x):
    """Wrap to [-pi, pi], leaving values already within untouched (bit for bit)."""
    x = np.asarray(x, dtype=np.float64)
    return np.where(np.abs(x) > np.pi, x - _TWO_PI * np.rint(x / _TWO_PI), x)


def _wrap_inplace(x):
    """Wrap to [-pi, pi] in place (exact for |x| < 3 pi: a single +-2 pi where needed)."""
    big = np.abs(x) > np.pi
    if big.any():
        x -= _TWO_PI * np.rint(x * (1.0 / _TWO_PI)) * big
    return x


def sincos(x):
    """(sin x, cos x) of float64 angles by the tangent of the half angle, t = tan(x / 2):
    sin x = 2 t / (1 + t^2), cos x = (1 - t^2) / (1 + t^2). Absolute error a few 1e-16 for
    |x| < 2 pi (checked against np.sin / np.cos in tests/test_reference.py).

    numpy's float64 sin and cos are scalar libm calls (about 15 ns each); its tan is vectorised
    (about 3 ns), so this is about 5x cheaper than np.sin plus np.cos.
    """
    t = np.multiply(x, 0.5)
    np.tan(t, out=t)
    t2 = t * t
    inv = t2 + 1.0
    np.reciprocal(inv, out=inv)
    t *= inv
    t *= 2.0
    np.subtract(1.0, t2, out=t2)
    t2 *= inv
    return t, t2


def _confirm(arm, Q, S, P, cphi, sphi, c1_in, s1_in, offsets, tol_cm, tol_dir):
    """FK of the returned angles: flag UNREACHABLE where the tool point or the approach misses.

    Q (4, 5, m) angles, S (4, m) status (updated), P (3, m) target tool points; cphi, sphi: the
    projected approach (cos phi_front, -sin phi_front); c1_in, s1_in: the IK's arm plane.
    """
    a1, a2, a3, a4, _ = arm.a
    d1, d5 = arm.d[0], arm.d[4]
    px, py, pz = P
    m = Q.shape[2]
    # trig of the returned angles: q1 of branch 0 (the back shoulder's q1 + pi: cos/sin negated,
    # rounding differences far below the tolerance), q2, q3, q4 of every branch
    X = np.empty((13, m))
    X[0] = Q[0, 0]
    X[1:5] = Q[:, 1]
    X[5:9] = Q[:, 2]
    X[9:13] = Q[:, 3]
    if np.any(offsets != 0):
        X[0] += offsets[0]
        X[1:5] += offsets[1]
        X[5:9] += offsets[2]
        X[9:13] += offsets[3]
    with np.errstate(over="ignore", invalid="ignore"):
        sn, cs = sincos(X)
    c1, s1 = cs[0], sn[0]
    c2, s2, c3, s3, c4, s4 = cs[1:5], sn[1:5], cs[5:9], sn[5:9], cs[9:13], sn[9:13]
    c23 = c2 * c3
    c23 -= s2 * s3
    s23 = s2 * c3
    s23 += c2 * s3
    cp = c23 * c4
    cp -= s23 * s4
    sp = s23 * c4
    sp += c23 * s4
    r = a2 * c2
    r += a1
    r += a3 * c23
    r += a4 * cp
    r -= d5 * sp
    y = a2 * s2
    y += a3 * s23
    y += a4 * sp
    y += d5 * cp
    r[2:] *= -1.0                 # back shoulder: (r cos(q1 + pi), r sin(q1 + pi)) = -r (c1, s1)
    ex = r * c1
    ex -= px
    ey = r * s1
    ey -= py
    ez = pz + y
    ez -= d1                      # -(d1 - y - pz)
    err = ex * ex
    err += ey * ey
    err += ez * ez
    miss = err > tol_cm * tol_cm
    # approach a = (-sp cos q1, -sp sin q1, -cp) against the projected target
    # (-sin phi_f c1, -sin phi_f s1, -cos phi) = (sphi c1_in, sphi s1_in, -cphi)
    sp[:2] *= -1.0                # front: -sp; back: -sp * (-1)
    ex = sp * c1
    ex -= sphi * c1_in
    ey = sp * s1
    ey -= sphi * s1_in
    ez = cp - cphi                # (-cp) - (-cphi), squared
    err = ex * ex
    err += ey * ey
    err += ez * ez
    miss |= err > tol_dir * tol_dir
    harmless = st.SINGULAR_ELBOW | st.SINGULAR_BASE | st.BAD_ORIENTATION
    miss &= (S & ~harmless) == 0
    if miss.any():
        S[miss] |= st.UNREACHABLE
