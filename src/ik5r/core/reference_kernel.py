"""The float closed-form IK of :mod:`ik5r.core.reference`, one chunk of poses at a time (core layer).

:func:`ik5r.core.reference.ik` validates its arguments, cuts the batch into chunks and runs
:meth:`Kernel.solve` on each; the stages below follow the module docstring of
:mod:`ik5r.core.reference` (joint 1, the approach, joint 5, the four branches, the joint limits;
the FK round trip is :mod:`ik5r.core.reference_check`). Work arrays are (3, chunk) or (chunk,) and
reused in place: the order of the float operations is the reference's, so each stage gives the
same bits wherever it is called from.
"""

from __future__ import annotations

import numpy as np

from . import status as st
from .arm import Arm
from .plane import plane_direction
from .reference_check import confirm

#: Tool point closer than this to the base axis (cm) counts as on it.
AXIS_TOLERANCE_CM = 1e-9
#: A direction component below this fraction of the vector's length counts as zero.
DIRECTION_TOLERANCE = 1e-12

_TWO_PI = 2.0 * np.pi


def _atan2(y, x, out=None):
    """np.arctan2, with float32 operands evaluated in float64 and rounded once. numpy picks its
    float32 arctan2 by CPU (AVX-512 SVML or libm), whose last bits differ between machines, so the
    float32 baseline would change with the machine; the rounded float64 angle is the same on every
    machine (and within half an ulp of the true one, as a good float32 libm's)."""
    if np.asarray(y).dtype != np.float32:
        return np.arctan2(y, x, out=out)
    angle = np.arctan2(np.asarray(y, np.float64), np.asarray(x, np.float64))
    if out is None:
        return angle.astype(np.float32)
    out[...] = angle
    return out


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


class Kernel:
    """The closed-form IK of one chunk of poses, written into slices of the result arrays."""

    def __init__(self, arm: Arm, dt, singular_sin_q3, tolerances, reach_tolerance, orientation_tolerance,
                 approach_plane=None):
        self.arm, self.dt, self.singular = arm, dt, float(singular_sin_q3)
        self.approach_plane = approach_plane
        self.reach, self.orientation = float(reach_tolerance), float(orientation_tolerance)
        self.tolerances = tolerances
        self.offsets = np.asarray(arm.theta_offset, dtype=np.float64)
        self.has_offset = bool(np.any(self.offsets != 0))
        self.sense = np.asarray(arm.sense, dtype=np.float64)
        # joints whose limits do not contain all of [-pi, pi]: (j, lo, hi)
        self.limited = [(j, lo, hi) for j, (lo, hi) in enumerate(arm.limits)
                        if not (lo <= -np.pi and hi >= np.pi)]

    def solve(self, p, a, n, o, near0, near4, Q, S, residual, q1_free):
        """Every branch of the chunk's poses into Q (4, 5, m), S (4, m), residual and q1_free (m,)."""
        P, A, Nv, Ov, bad = self._inputs(p, a, n, o)
        any_bad = bool(bad.any())
        rho, c1, s1, theta1 = self._joint1(P, A, near0, ~bad, any_bad, q1_free)
        cphi, sphi, phi_f, no_direction, bad_orientation = self._approach(A, Nv, Ov, c1, s1, residual)
        if Nv is not None:
            q5_f, no_roll = _roll(Nv, Ov, c1, s1)
            q5_b = _opposite(q5_f)
            invalid_rows = no_direction | no_roll
        else:
            q5 = np.asarray(_wrap_scalar(self.sense[4] * near4 + self.offsets[4]), dtype=self.dt)
            q5_f = np.broadcast_to(q5, (P.shape[1],))
            q5_b = q5_f
            invalid_rows = no_direction
        if any_bad:
            invalid_rows |= bad

        base = np.zeros(P.shape[1], dtype=np.int64)
        base[invalid_rows] = st.INVALID
        base[q1_free] |= st.SINGULAR_BASE
        base[bad_orientation] |= st.BAD_ORIENTATION
        for back in (0, 1):
            self._shoulder_branches(back, Q, S, base, rho, P[2], cphi, sphi,
                                    -phi_f if back else phi_f, _opposite(theta1) if back else theta1,
                                    q5_b if back else q5_f)
        self._offsets_and_limits(Q, S)
        if self.tolerances is not None:
            confirm(self.arm, Q, S, P, cphi, sphi, c1, s1, self.offsets, *self.tolerances)
        if invalid_rows.any():
            Q[:, :, invalid_rows] = np.nan
            S[:, invalid_rows] = st.INVALID
        if any_bad:
            residual[bad] = np.nan

    def _inputs(self, p, a, n, o):
        """Private (3, m) copies of p, a (n, o: None without roll) and the rows that are not
        finite or beyond :func:`input_limit`: solved as placeholders (and flagged INVALID)."""
        dt = self.dt
        has_roll = n is not None
        P = np.array(p.T, dtype=dt, order="C")      # private (3, chunk) copies
        A = np.array(a.T, dtype=dt, order="C")
        Nv = Ov = None
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
        if bad.any():
            P[:, bad] = 0
            A[:, bad] = 1
            if has_roll:
                Nv[:, bad] = 1
                Ov[:, bad] = 1
        return P, A, Nv, Ov, bad

    def _joint1(self, P, A, near0, finite, any_bad, q1_free):
        """The arm's plane: (rho, c1, s1, theta1), its cos/sin without trigonometry; on the axis
        the approach's plane, or (vertical approach) q1 free from near0 (q1_free set)."""
        px, py, _ = P
        ax, ay, az = A
        count = P.shape[1]
        rho = px * px
        rho += py * py
        np.sqrt(rho, out=rho)
        length = rho
        if self.approach_plane is not None:
            px, py = plane_direction(px, py, ax, ay, self.approach_plane)
            length = np.hypot(px, py)
        with np.errstate(invalid="ignore", divide="ignore"):
            inv_rho = np.reciprocal(length)
            c1 = px * inv_rho                  # fixed below where the point is on the axis
            s1 = py * inv_rho
        theta1 = _atan2(py, px)
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
            theta1[on_axis] = _atan2(ayo, axo)
            idx = on_axis[free]
            if idx.size:
                t = _wrap_scalar(self.sense[0] * np.broadcast_to(near0, (count,))[idx] + self.offsets[0])
                theta1[idx] = t
                c1[idx] = np.cos(t)
                s1[idx] = np.sin(t)
        return rho, c1, s1, theta1

    def _approach(self, A, Nv, Ov, c1, s1, residual):
        """The approach projected onto the arm's plane (front-shoulder frame): (cphi, sphi, phi_f,
        no_direction, bad_orientation); the angle removed goes into residual."""
        ax, ay, az = A
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
        _atan2(a_nrm, a_in, out=residual)
        np.sqrt(a_len2, out=a_len2)
        bad_orientation = a_nrm > a_len2 * self.orientation
        if Nv is not None:
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
        phi_f = _atan2(-a_rad, -az)
        return cphi, sphi, phi_f, no_direction, bad_orientation

    def _elbow(self, back, base, rho, pz, cphi, sphi):
        """Wrist centre (joint 4 axis) in the arm's plane and the elbow of one shoulder:
        (xw, yw, c3, s3 = |sin q3|, status)."""
        a1, a2, a3, a4, _ = self.arm.a
        d1, d5 = self.arm.d[0], self.arm.d[4]
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
        yw = (d1 - pz) - off_y
        c3 = xw * xw
        c3 += yw * yw
        c3 -= a2 * a2 + a3 * a3
        c3 *= 1.0 / (2.0 * a2 * a3)
        status = base.copy()
        status[np.abs(c3) > 1 + self.reach] |= st.UNREACHABLE
        np.minimum(c3, 1.0, out=c3)
        np.maximum(c3, -1.0, out=c3)
        s3 = 1.0 - c3
        s3 *= 1.0 + c3
        np.sqrt(s3, out=s3)
        status[s3 <= self.singular] |= st.SINGULAR_ELBOW
        return xw, yw, c3, s3, status

    def _shoulder_branches(self, back, Q, S, base, rho, pz, cphi, sphi, phi, q1, q5):
        """The two elbow branches of one shoulder into Q[b], S[b] (b = 2 back + down)."""
        a2, a3 = self.arm.a[1], self.arm.a[2]
        xw, yw, c3, s3, status = self._elbow(back, base, rho, pz, cphi, sphi)
        # q2 = atan2(yw, xw) -+ atan2(a3 s3, a2 + a3 c3), as one atan2 of a complex product
        k1 = a3 * c3
        k1 += a2
        k2 = a3 * s3
        u = xw * k1
        v = yw * k2
        w = yw * k1
        z = xw * k2
        for down in (0, 1):
            b = 2 * back + down
            qb = Q[b]
            qb[0] = q1
            if down:
                _atan2(w + z, u - v, out=qb[1])
                _atan2(s3, c3, out=qb[2])
                np.negative(qb[2], out=qb[2])
            else:
                _atan2(w - z, u + v, out=qb[1])
                _atan2(s3, c3, out=qb[2])
            q4 = qb[3]
            np.subtract(phi, qb[1], out=q4)
            q4 -= qb[2]
            _wrap_inplace(q4)
            qb[4] = q5
            S[b] = status

    def _offsets_and_limits(self, Q, S):
        """Joint angles of the arm (theta offsets removed, reversed joints negated) and its joint
        limits (OUT_OF_LIMITS; a representative beyond +-pi where only that is within them)."""
        if self.has_offset:
            for j in range(5):
                if self.offsets[j] != 0:
                    Q[:, j] -= self.offsets[j]
                    _wrap_inplace(Q[:, j])
        for j in np.flatnonzero(self.sense < 0):
            np.negative(Q[:, j], out=Q[:, j])
        for j, lo, hi in self.limited:
            qj = Q[:, j]
            if hi > np.pi:   # the representative above pi may be the one within the limits
                shift = (qj < lo - 1e-12) & (qj + _TWO_PI <= hi + 1e-12)
                qj[shift] += _TWO_PI
            if lo < -np.pi:
                shift = (qj > hi + 1e-12) & (qj - _TWO_PI >= lo - 1e-12)
                qj[shift] -= _TWO_PI
            S[(qj < lo - 1e-12) | (qj > hi + 1e-12)] |= st.OUT_OF_LIMITS


def _roll(Nv, Ov, c1, s1):
    """q5 of the front shoulder from n and o (q5 = atan2(n . e, o . e), e = (s1, -c1, 0)) and the
    rows where n, o have no component along e (no roll)."""
    nx, ny, _ = Nv
    ox, oy, _ = Ov
    s5 = nx * s1
    s5 -= ny * c1
    c5 = ox * s1
    c5 -= oy * c1
    q5_f = _atan2(s5, c5)
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
    return q5_f, no_roll


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
