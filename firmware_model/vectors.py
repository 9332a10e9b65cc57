"""Shared test vectors of the fixed-point IK: random reachable poses and the directed edge set.

Every check of the C solver, the bit-accurate models and the hardware draws its poses from here, so
they all see the same cases: zero vectors, full-scale words (the most negative word in every input),
the tool point on the base axis (vertical and horizontal approach), straight and folded elbow,
unreachable (too far, too near), approach off the arm's plane and perpendicular to it, n/o with no
component across the plane, and the seed paper's pose q = [0, -pi/2, 0, -pi/2, 0].
"""

from __future__ import annotations

import math

import numpy as np

from ik5r import reference
from ik5r.fxconfig import Constants, quantize


class Poses:
    """Pose rows as word arrays: p, a, n, o (N, 3), roll, back, down (N,) bool, q5 (N,)."""

    def __init__(self, p, a, n, o, roll, back, down, q5):
        self.p, self.a, self.n, self.o = (np.asarray(v, dtype=np.int64).reshape(-1, 3) for v in (p, a, n, o))
        self.roll, self.back, self.down = (np.asarray(v, dtype=bool) for v in (roll, back, down))
        self.q5 = np.asarray(q5, dtype=np.int64)

    def __len__(self):
        return len(self.p)

    def args(self):
        return self.p, self.a, self.n, self.o, self.roll, self.back, self.down, self.q5

    def driver_lines(self):
        cols = np.column_stack([self.p, self.a, self.n, self.o, self.roll, self.back, self.down, self.q5])
        return ["S " + " ".join(map(str, row)) for row in cols.tolist()]


def every_branch(p, a, n, o, q5):
    """Each pose with the 4 branches, with and without n/o: 8 rows per pose."""
    count = len(p)
    rep = lambda v: np.repeat(np.asarray(v), 8, axis=0)  # noqa: E731
    variant = np.tile(np.arange(8), count)
    return Poses(rep(p), rep(a), rep(n), rep(o), (variant & 4) != 0, (variant & 2) != 0,
                 (variant & 1) != 0, rep(q5))


def quantize_pose(k: Constants, p, a, n, o):
    """Float poses (cm, unit vectors) to words: (p_l, a_u, n_u, o_u)."""
    c = k.cfg
    return (quantize(p, c.frac_length, c)[0], quantize(a, c.frac_unit, c)[0],
            quantize(n, c.frac_unit, c)[0], quantize(o, c.frac_unit, c)[0])


def random_poses(k: Constants, count: int, seed: int) -> Poses:
    """Reachable poses: FK of random joints within the limits, quantised; every branch/roll."""
    rng = np.random.default_rng(seed)
    q = reference.random_joints(k.arm, count, rng)
    p, n, o, a = reference.fk(k.arm, q)
    words = quantize_pose(k, p, a, n, o)
    q5 = rng.integers(-k.pi_a, k.pi_a + 1, count)
    return every_branch(*words, q5)


def edge_poses(k: Constants) -> Poses:
    """Directed edge set (each pose in every branch, with and without n/o)."""
    arm = k.arm
    a1, a4, d1, d5 = arm.a[0], arm.a[3], arm.d[0], arm.d[4]
    real = []  # (p, a, n, o) in cm / unit vectors

    def add(p, a, n=(1.0, 0.0, 0.0), o=(0.0, 1.0, 0.0)):
        real.append((p, a, n, o))

    # Tool point on the base axis: vertical approach (q1 free) and horizontal approaches.
    for z in (-20.0, -5.0, 0.0, 10.0, 34.0):
        for a in ((0, 0, 1), (0, 0, -1), (1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0.6, -0.8, 0),
                  (0.6, 0.0, -0.8)):
            add((0.0, 0.0, z), a)
            add((0.0, 0.0, z), a, (0, 0, 1), (0.6, 0.8, 0))
    # Straight (q3 = 0) and folded (q3 = pi) elbow, several arm positions: FK gives every vector.
    rng = np.random.default_rng(7)
    for q3 in (0.0, math.pi, -math.pi, 1e-4, math.pi - 1e-4):
        for _ in range(6):
            q = rng.uniform(-math.pi, math.pi, 5)
            q[2] = q3
            p, n, o, a = reference.fk(arm, q)
            add(tuple(p), tuple(a), tuple(n), tuple(o))
    # The paper's pose and exact zero joints.
    for q in ((0, -math.pi / 2, 0, -math.pi / 2, 0), (0, 0, 0, 0, 0), (math.pi, 0, 0, 0, 0)):
        p, n, o, a = reference.fk(arm, np.array(q, float))
        add(tuple(p), tuple(a), tuple(n), tuple(o))
    # Unreachable: too far, and too near (wrist centre on the joint 2 axis: D = 0) and around it.
    for p in ((30, 0, 0), (0, 40, 10), (-50, 3, -20), (60, 60, 60), (-100, -100, 100), (1000, 0, 0)):
        add(p, (0, 0, -1))
        add(p, (0.6, 0, -0.8))
    for q1 in (0.0, 0.7, -2.0, math.pi):
        for dr, dz in ((0, 0), (0.2, 0), (0, 0.2), (0.5, 0.5), (0.49, 0), (0.51, 0)):
            r = a1 + a4 + dr
            add((r * math.cos(q1), r * math.sin(q1), d1 - d5 + dz), (0, 0, -1))
    # Approach off the arm's plane and perpendicular to it (no in-plane component: invalid).
    for q1 in (0.0, 0.3, -1.9, math.pi / 2):
        c1, s1 = math.cos(q1), math.sin(q1)
        p = (12 * c1, 12 * s1, 5.0)
        add(p, (-s1, c1, 0))                      # perpendicular
        add(p, (s1, -c1, 0))
        add(p, (0.3 * c1 - 0.6 * s1, 0.3 * s1 + 0.6 * c1, -0.74))   # off-plane
        add(p, (0.0 * c1 - 0.99 * s1, 0.99 * c1, 0.141))
        add(p, (c1, s1, 0), (0, 0, 1), (0, 0, -1))  # n, o with no component: q5 invalid
        add(p, (c1, s1, 0), (0, 0, 0), (0, 0, 0))
    cols = [np.array([r[i] for r in real], dtype=float) for i in range(4)]
    norm = lambda v: v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-300)  # noqa: E731
    p_w, a_w, n_w, o_w = quantize_pose(k, cols[0], norm(cols[1]), norm(cols[2]), norm(cols[3]))
    q5 = np.zeros(len(p_w), dtype=np.int64)

    # Raw words: zeros, full scale, the most negative word in every input slot.
    lo, hi, one, pi = k.word_min, k.word_max, k.one_u, k.pi_a
    lsb_cases = np.array([
        # Back shoulder gives xw = yw = word_min: xw^2 + yw^2 = 2**63, one past int64.
        [hi, 0, hi, 0, 0, lo, one, 0, 0, 0, one, 0],
        # One LSB off the base axis, vertical approach.
        [1, 0, p_w[0, 2], 0, 0, -one, one, 0, 0, 0, one, 0],
        [0, -1, p_w[0, 2], 0, 0, -one, one, 0, 0, 0, one, 0],
    ], dtype=np.int64)
    p_w = np.concatenate([p_w, lsb_cases[:, 0:3]])
    a_w = np.concatenate([a_w, lsb_cases[:, 3:6]])
    n_w = np.concatenate([n_w, lsb_cases[:, 6:9]])
    o_w = np.concatenate([o_w, lsb_cases[:, 9:12]])
    q5 = np.concatenate([q5, np.zeros(len(lsb_cases), dtype=np.int64)])
    base = np.concatenate([p_w[-1], a_w[-1], n_w[-1], o_w[-1], [pi // 3]])  # a valid-ish pose
    raw = [np.zeros(13, dtype=np.int64), np.full(13, lo), np.full(13, hi)]
    for slot in range(13):
        for value in (lo, hi, 0, -1, 1, one, -one):
            row = base.copy()
            row[slot] = value
            raw.append(row)
    specials = np.array([lo, lo + 1, -one, -1, 0, 1, one, hi - 1, hi, pi, -pi])
    rng = np.random.default_rng(11)
    raw.extend(rng.choice(specials, size=(300, 13)))
    raw.extend(rng.integers(lo, hi + 1, size=(200, 13)))
    raw = np.array(raw, dtype=np.int64)
    p_w = np.concatenate([p_w, raw[:, 0:3]])
    a_w = np.concatenate([a_w, raw[:, 3:6]])
    n_w = np.concatenate([n_w, raw[:, 6:9]])
    o_w = np.concatenate([o_w, raw[:, 9:12]])
    q5 = np.concatenate([q5, raw[:, 12]])
    return every_branch(p_w, a_w, n_w, o_w, q5)
