"""Shared test vectors of the fixed-point IK: random reachable poses and the directed edge set.

Every check of the C solver, the bit-accurate models and the hardware draws its poses from here, so
they all see the same cases: zero vectors, full-scale words (the most negative word in every input),
the tool point on the base axis (vertical and horizontal approach) and within 1e-6 cm of it
(reachable, several approach tilts), straight and folded elbow,
unreachable (too far, too near), approach off the arm's plane and perpendicular to it, n/o with no
component across the plane, and the seed paper's pose q = [0, -pi/2, 0, -pi/2, 0].

:func:`directed_poses` is a small directed set (a few hundred rows, part of :func:`edge_poses`)
for the runs that cannot afford the whole edge set: the HDL simulations of the IK core. The IK
core's payload fields are the names of :data:`ik5r.firmware_model.poses.FIELDS`: every set is a
:class:`~ik5r.firmware_model.poses.PoseBatch`.
"""

from __future__ import annotations

import math

import numpy as np

from ik5r.core import reference
from ik5r.core.fxconfig import Constants, quantize
from ik5r.core.status_cases import near_axis_joints, status_cases
from ik5r.firmware_model.poses import PoseBatch, concat, every_branch, pose_words


def random_poses(k: Constants, count: int, seed: int) -> PoseBatch:
    """Reachable poses: FK of random joints within the limits, quantised; every branch/roll."""
    rng = np.random.default_rng(seed)
    q = reference.random_joints(k.arm, count, rng)
    p, n, o, a = reference.fk(k.arm, q)
    words = pose_words(k.cfg, p, a, n, o)[:4]
    q5 = rng.integers(-k.pi_a, k.pi_a + 1, count)
    return every_branch(*words, q5)


def near_axis_poses(k: Constants, radii=None, pitches=None) -> PoseBatch:
    """Reachable poses (FK) with the tool point within 1e-6 cm of the base axis, at several
    approach tilts (:func:`ik5r.core.status_cases.near_axis_joints`; its defaults where None)."""
    kwargs = {name: value for name, value in (("radii", radii), ("pitches", pitches)) if value is not None}
    q = near_axis_joints(k.arm, **kwargs)
    p, n, o, a = reference.fk(k.arm, q)
    words = pose_words(k.cfg, p, a, n, o)[:4]
    return every_branch(*words, quantize(q[:, 4], k.cfg.frac_angle, k.cfg)[0])


def directed_poses(k: Constants) -> PoseBatch:
    """The small directed set, each pose in every branch, with and without n/o: the paper's pose
    q = [0, -pi/2, 0, -pi/2, 0]; tool point on the base axis with vertical (q1 free) and horizontal
    approach, and a few near-axis poses (:func:`near_axis_poses`); nothing at all; straight and folded elbow; unreachable (too far, too close);
    off-plane approaches; approach normal to the arm's plane and n, o with no in-plane component
    (invalid); the directed status cases of :mod:`ik5r.core.status_cases`; q5 defaults at the word
    limits; full-scale and most negative words."""
    c = k.cfg
    real = []    # (p, a, n, o, q5): cm / unit vectors / radians

    def joints(q):
        p, n, o, a = reference.fk(k.arm, np.asarray(q, dtype=float))
        real.append((p, a, n, o, 0.3))

    def add(p, a, n=(0, 0, 0), o=(0, 0, 0), q5=0.0):
        real.append((p, a, n, o, q5))

    joints([0, -math.pi / 2, 0, -math.pi / 2, 0])
    add((0, 0, 20), (0, 0, -1))
    add((0, 0, 20), (0, 0, 1), (1, 0, 0), (0, 1, 0))
    add((0, 0, 15), (1, 0, 0))
    add((0, 0, 15), (0, -1, 0), (0, 0, 1), (1, 0, 0))
    joints([0.3, -1.0, 0.0, 0.2, 0.1])
    joints([-0.7, -0.5, math.pi, 0.4, -0.2])
    joints([1.2, -1.3, 1e-4, 0.3, 0.5])
    add((35, 0, 5), (1, 0, 0))
    add((0.5, 0.2, 5), (0, 0, -1))
    add((10, 10, 10), (0, 0, 1), (1, 0, 0), (0, 1, 0))
    add((12, 5, 8), (0.6, -0.8, 0.0))
    add((12, 0, 8), (0, 1, 0), (1, 0, 0), (0, 0, 1))
    add((12, 0, 8), (0.3, 0.9, -0.3), (0.2, 0.1, 0.9), (0.9, -0.3, 0.1))
    add((-7, -9, 3), (-0.5, -0.5, -0.7))
    add((12, 0, 8), (1, 0, 0), (0, 1, 0), (0, 1, 0))
    # The directed status cases (ik5r.core.status_cases): every status class, compared with the float.
    for _, _, (p, a, n, o) in status_cases(k.arm):
        add(p, a, (0, 0, 0) if n is None else n, (0, 0, 0) if o is None else o)
    words = _directed_words(k)
    cols = [np.array([r[i] for r in real], dtype=float) for i in range(4)]
    p_w, a_w, n_w, o_w = pose_words(k.cfg, *cols)[:4]
    q5 = quantize(np.array([r[4] for r in real]), c.frac_angle, c)[0]
    wcols = [np.array([r[i] for r in words], dtype=np.int64) for i in range(5)]
    listed = every_branch(np.concatenate([p_w, wcols[0]]), np.concatenate([a_w, wcols[1]]),
                          np.concatenate([n_w, wcols[2]]), np.concatenate([o_w, wcols[3]]),
                          np.concatenate([q5, wcols[4]]))
    # A few of the near-axis poses (the whole set is in edge_poses).
    return concat(listed, near_axis_poses(k, (0.0, 1e-7, 1e-6), (0.1, math.pi / 2, -1.5)))


def _directed_words(k: Constants) -> list:
    """The word-level poses of :func:`directed_poses` (p, a, n, o, q5 as words): nothing at all,
    q5 defaults at the word limits, full-scale and most negative words, mixed extremes and a few
    seeded random picks of them."""
    lo, hi, one = k.word_min, k.word_max, k.one_u
    p1 = (1 << k.cfg.frac_length, 2 << k.cfg.frac_length, 3 << k.cfg.frac_length)
    words = [((0, 0, 0),) * 4 + (0,), (p1, (0, 0, -one), (0, 0, 0), (0, 0, 0), hi),
             (p1, (0, 0, -one), (0, 0, 0), (0, 0, 0), lo),
             ((lo,) * 3,) * 4 + (lo,), ((hi,) * 3,) * 4 + (hi,),
             ((lo, hi, lo), (hi, lo, hi), (lo, hi, 0), (hi, lo, 0), lo),
             ((hi, lo, 0), (lo, 0, hi), (0, lo, lo), (lo, 0, hi), 1),
             ((lo, 0, hi), (0, lo, 0), (hi, hi, 0), (0, 0, lo), -1),
             ((0, lo, 0), (0, 0, lo), (lo, 0, 0), (0, lo, 0), 0),
             ((lo, lo, 0), (1, -1, 0), (1, 0, 0), (0, 1, 0), 0),
             ((1, 0, 0), (0, 0, 1), (0, 1, 0), (1, 0, 0), 0),
             ((-1, -1, -1),) * 4 + (-1,)]
    rng = np.random.default_rng(99)
    for _ in range(6):
        w = [int(rng.choice([lo, hi, 0, 1, -1, int(rng.integers(lo, hi, endpoint=True))])) for _ in range(13)]
        words.append((w[0:3], w[3:6], w[6:9], w[9:12], w[12]))
    return words


def edge_poses(k: Constants) -> PoseBatch:
    """Directed edge set (each pose in every branch, with and without n/o), :func:`directed_poses`
    first."""
    return concat(directed_poses(k), near_axis_poses(k), _more_edges(k))


def _real_edges(arm) -> list:
    """The float edge poses (p, a, n, o) in cm / unit vectors (not yet normalised)."""
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
    return real


def _raw_word_rows(k: Constants, base: np.ndarray) -> np.ndarray:
    """(m, 13) raw word rows (p, a, n, o, q5): zeros, full scale, every input slot of ``base`` set
    to each awkward word, and random rows of awkward and of any words."""
    lo, hi, one, pi = k.word_min, k.word_max, k.one_u, k.pi_a
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
    return np.array(raw, dtype=np.int64)


def _more_edges(k: Constants) -> PoseBatch:
    real = _real_edges(k.arm)
    cols = [np.array([r[i] for r in real], dtype=float) for i in range(4)]
    norm = lambda v: v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-300)  # noqa: E731
    p_w, a_w, n_w, o_w = pose_words(k.cfg, cols[0], norm(cols[1]), norm(cols[2]), norm(cols[3]))[:4]
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
    raw = _raw_word_rows(k, base)
    p_w = np.concatenate([p_w, raw[:, 0:3]])
    a_w = np.concatenate([a_w, raw[:, 3:6]])
    n_w = np.concatenate([n_w, raw[:, 6:9]])
    o_w = np.concatenate([o_w, raw[:, 9:12]])
    q5 = np.concatenate([q5, raw[:, 12]])
    return every_branch(p_w, a_w, n_w, o_w, q5)
