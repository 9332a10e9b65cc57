"""Float reference of the 5R arm: forward kinematics and closed-form IK with every branch.

Vectorised over batches with numpy; ``dtype`` may be float64 (the reference) or float32 (what a
soft CPU with a single-precision FPU would compute, for the quantisation report).

Geometry (standard DH, see docs/algorithm.md): joint 1 turns the arm's vertical plane about the base
axis; in that plane, with x1 radial and y1 pointing down, joints 2-4 form a planar chain
(a2, a3, a4) and the tool point sits d5 along the approach a = z5. With phi = q2 + q3 + q4
(joint angles here are the DH thetas, theta_offset + sense * q of the joint readings q):

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
from .plane import fixed_plane  # noqa: F401  (reference.fixed_plane)
from .reference_kernel import Kernel

N_BRANCHES = 4
#: Branch names by index (2 * shoulder_back + elbow_down).
BRANCH_NAMES = ("front_up", "front_down", "back_up", "back_down")
#: A cosine of q3 beyond 1 by more than this is unreachable rather than rounding noise.
REACH_TOLERANCE = 1e-9
#: Off-plane approach (sine of its angle to the arm's plane) or n, o, a frame error above this:
#: BAD_ORIENTATION (see :mod:`ik5r.core.status`).
ORIENTATION_TOLERANCE = 1e-3

#: Default FK round-trip tolerances per dtype: (tool point, cm; approach, unit vector).
CONFIRM_TOLERANCE = {np.float64: (1e-6, 1e-9), np.float32: (1e-2, 1e-4)}


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
        ti = _dh(arm.theta_offset[i] + arm.sense[i] * q[..., i], arm.a[i], arm.alpha[i], arm.d[i], dtype)
        t = ti if t is None else t @ ti
    return t


def fk(arm: Arm, q, dtype=np.float64):
    """Forward kinematics in closed form (see the module docstring): (p, n, o, a), each (..., 3).

    Equal to :func:`fk_matrix` (the product of the DH matrices) to rounding, and much faster.
    """
    q = np.asarray(q, dtype=dtype)
    # in ``dtype`` (float32 stays float32 throughout); sense * q is exact
    t = q * np.asarray(arm.sense, dtype=dtype) + np.asarray(arm.theta_offset, dtype=dtype)
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


def ik(arm: Arm, p, a, n=None, o=None, near=None, *, singular_sin_q3=1e-3,
       reach_tolerance=REACH_TOLERANCE, orientation_tolerance=ORIENTATION_TOLERANCE,
       dtype=np.float64, confirm_tolerance_cm="auto", confirm_tolerance_dir="auto",
       approach_plane=None) -> IKResult:
    """Closed-form IK of N poses, all four branches (see the module docstring).

    p, a: (N, 3) tool point (cm) and approach (any length). n, o: (N, 3) or None (both or
    neither): then q5 keeps ``near[4]`` (0 without ``near``). ``near``: (5,) or (N, 5) joint
    vector that a free q1 and an unspecified q5 take (the choice of branch is
    :meth:`IKResult.choose`). The FK round trip tolerances default ("auto") to
    :data:`CONFIRM_TOLERANCE` of the dtype; ``confirm_tolerance_cm=None`` skips the round trip.
    ``approach_plane`` (:func:`fixed_plane`): the arm's plane as the fixed-point solver takes it,
    for float64 on the solver's own input words; None: the tool point's.
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
    kernel = Kernel(arm, dt, singular_sin_q3, tolerances, reach_tolerance, orientation_tolerance,
                    approach_plane)
    for lo in range(0, count, CHUNK):
        sl = slice(lo, min(count, lo + CHUNK))
        near_c = near_q if near_q.ndim == 1 else near_q[sl]
        kernel.solve(p[sl], a[sl], None if n is None else n[sl], None if o is None else o[sl],
                     near_c[..., 0], near_c[..., 4], Q[:, :, sl], S[:, sl], residual[sl], q1_free[sl])
    return IKResult(Q.transpose(2, 0, 1), S.T, residual, q1_free)
