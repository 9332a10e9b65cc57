"""The directed status cases: one pose per situation a status names, in float (cm, unit vectors).

Every layer (float reference, fixed-point model, C solver, HDL core) must give each case the same
status class (:func:`ik5r.core.status.status_class`) on every branch; ``tests/test_status.py`` prints
and checks the table, ``ik5r.firmware_model.vectors.directed_poses`` feeds the cases to the C and HDL
bit-exact tests.
"""

from __future__ import annotations

import math

import numpy as np

from . import reference
from .arm import Arm

#: The seed paper's check pose: the arm stretched straight up.
SEED_CHECK_POSE = (0.0, -math.pi / 2, 0.0, -math.pi / 2, 0.0)


def _rotate_z(v, angle):
    c, s = math.cos(angle), math.sin(angle)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]])


#: Distances of the tool point from the base axis (cm) and tool pitches phi = q2 + q3 + q4 (rad,
#: the approach's tilt from vertical is |sin phi|) of :func:`near_axis_joints`.
NEAR_AXIS_RADII = (0.0, 1e-8, 1e-7, 3e-7, 1e-6)
NEAR_AXIS_PITCHES = (0.01, 0.1, 0.5, 1.2, math.pi / 2, 2.3, -0.4, -1.5)


def near_axis_joints(arm: Arm, radii=NEAR_AXIS_RADII, pitches=NEAR_AXIS_PITCHES) -> np.ndarray:
    """Joints (m, 5) whose tool point lies at each radius from the base axis, at each pitch, in two
    arm directions: the elbow at 1 rad, q2 solved from r = a1 + a2 c2 + a3 c23 + a4 c(phi) -
    d5 s(phi) (angles with the arm's offsets), q5 varied. Reachable by construction (FK poses)."""
    a1, a2, a3, a4, _ = arm.a
    d5, t3 = arm.d[4], 1.0
    gain = complex(a2 + a3 * math.cos(t3), a3 * math.sin(t3))
    rows = []
    for index, (radius, phi, t1) in enumerate((r, f, t) for r in radii for f in pitches for t in (0.4, -2.2)):
        wanted = radius - a1 - a4 * math.cos(phi) + d5 * math.sin(phi)   # = |gain| cos(t2 + arg gain)
        t2 = math.acos(wanted / abs(gain)) - math.atan2(gain.imag, gain.real)
        t = np.array([t1, t2, t3, phi - t2 - t3, 0.3 * index - 2.0])
        rows.append(t - np.asarray(arm.theta_offset, dtype=float))
    return np.array(rows)


def status_cases(arm: Arm) -> list[tuple[str, str, tuple]]:
    """[(name, expected class, (p, a, n, o))]: the class of at least one branch (for a pose made by
    forward kinematics, the branch of its own joints); n, o None for position and approach only."""
    def pose_of(q):
        p, n, o, a = reference.fk(arm, np.asarray(q, dtype=float))
        return p, a, n, o

    generic = pose_of([0.3, -1.0, 0.4, 0.2, 0.1])
    # Tool point on the base axis with a horizontal approach: phi = pi/2, q2 = -0.5, and q2 + q3
    # such that r = a1 + a2 cos q2 + a3 cos(q2 + q3) - d5 = 0 (the arm of record's offsets are 0).
    a1, a2, a3 = arm.a[:3]
    q23 = -math.acos((arm.d[4] - a1 - a2 * math.cos(-0.5)) / a3)
    on_axis = pose_of([0.0, -0.5, q23 + 0.5, math.pi / 2 - q23, 0.0])
    on_axis[0][:2] = 0.0
    p, a, n, o = generic
    skew = o + 0.05 * n
    cases = [
        ("straight elbow (seed check pose)", "singular_elbow", pose_of(SEED_CHECK_POSE)),
        ("folded elbow", "singular_elbow", pose_of([-0.7, -0.5, math.pi, 0.4, -0.2])),
        ("generic reachable", "ok", generic),
        ("generic, no n/o", "ok", (p, a, None, None)),
        ("base axis, vertical approach", "singular_base",
         (np.array([0.0, 0, 20]), np.array([0.0, 0, 1]), np.array([1.0, 0, 0]), np.array([0.0, 1, 0]))),
        ("base axis, horizontal approach", "ok", on_axis),
        # Near the axis the approach sets the arm's plane. Its horizontal part points away from
        # the axis along the tool point's (phi < 0), so that a config whose words put the point on
        # the axis (q18) keeps the branches of the float (the front shoulder faces the approach).
        ("1e-6 cm off the base axis, approach tilted 0.5 rad", "ok",
         pose_of(near_axis_joints(arm, (1e-6,), (-0.5,))[0])),
        ("1e-7 cm off the base axis, approach horizontal", "ok",
         pose_of(near_axis_joints(arm, (1e-7,), (-math.pi / 2,))[1])),
        ("off-plane approach (frame rotated 0.2 rad about z)", "bad_orientation",
         (p, _rotate_z(a, 0.2), _rotate_z(n, 0.2), _rotate_z(o, 0.2))),
        ("off-plane approach, no n/o", "bad_orientation", (p, _rotate_z(a, 0.2), None, None)),
        ("off-plane a = (0.577, 0.577, 0.577), n = x, o = y", "bad_orientation",
         (p, np.full(3, 1 / math.sqrt(3)), np.array([1.0, 0, 0]), np.array([0.0, 1, 0]))),
        ("non-orthogonal n, o", "bad_orientation", (p, a, n, skew / np.linalg.norm(skew))),
        ("left-handed n, o", "bad_orientation", (p, a, n, -o)),
        ("unreachable (too far)", "unreachable+singular_elbow", (np.array([60.0, 0, 5]), np.array([1.0, 0, 0]), None, None)),
        ("zero approach", "invalid", (p, np.zeros(3), n, o)),
        ("zero n, o", "invalid", (p, a, np.zeros(3), np.zeros(3))),
        ("huge position |p| = 1e155", "invalid", (np.array([1e155, 0, 0]), a, n, o)),
        ("NaN position", "invalid", (np.array([math.nan, 0, 0]), a, n, o)),
    ]
    return [(name, expected, tuple(None if v is None else np.asarray(v, dtype=float) for v in pose))
            for name, expected, pose in cases]
