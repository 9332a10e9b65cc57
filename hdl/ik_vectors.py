"""Stimulus for the IK core (:class:`~ik5r.hdl.ik_core.IKCore`): random reachable poses and the
directed set, as int64 arrays keyed by the core's input payload fields, and the model's answer.

Used by ``tests/test_ik_core.py`` (Amaranth simulator) and the cocotb testbench (``ik5r sim
--block ik``).
"""

from __future__ import annotations

import math

import numpy as np

from ik5r.arm import Arm, load_arm
from ik5r.fxconfig import Constants, quantize
from ik5r.reference import fk, random_joints

__all__ = ["INPUTS", "OUTPUTS", "random_poses", "directed_poses", "concat", "solve"]

INPUTS = ("px", "py", "pz", "ax", "ay", "az", "nx", "ny", "nz", "ox", "oy", "oz",
          "has_roll", "q5_default", "shoulder_back", "elbow_down")
OUTPUTS = ("q1", "q2", "q3", "q4", "q5", "status")


def _pack(p, a, n, o, roll, q5d, back, down) -> dict[str, np.ndarray]:
    out = {}
    for name, value in (("p", p), ("a", a), ("n", n), ("o", o)):
        value = np.asarray(value, dtype=np.int64).reshape(-1, 3)
        for axis, column in zip("xyz", value.T):
            out[f"{name}{axis}"] = column.copy()
    out.update(has_roll=np.asarray(roll, dtype=np.int64), q5_default=np.asarray(q5d, dtype=np.int64),
               shoulder_back=np.asarray(back, dtype=np.int64), elbow_down=np.asarray(down, dtype=np.int64))
    return {key: out[key] for key in INPUTS}


def random_poses(k: Constants, count: int, rng: np.random.Generator, arm: Arm | None = None):
    """Reachable poses: FK of joints uniform within the limits, quantised; the four branches in
    turn (shoulder_back, elbow_down = index bits), roll given for ~70 %, a random q5 default."""
    arm = arm or load_arm()
    c = k.cfg
    q = random_joints(arm, count, rng)
    p, n, o, a = fk(arm, q)
    index = np.arange(count)
    return _pack(quantize(p, c.frac_length, c)[0], quantize(a, c.frac_unit, c)[0],
                 quantize(n, c.frac_unit, c)[0], quantize(o, c.frac_unit, c)[0],
                 rng.random(count) < 0.7,
                 quantize(rng.uniform(-math.pi, math.pi, count), c.frac_angle, c)[0],
                 index % 4 >= 2, index % 2 == 1)


def directed_poses(k: Constants, arm: Arm | None = None):
    """The directed set, every pose in all four branches: the paper's pose q = [0, -pi/2, 0,
    -pi/2, 0] (with and without roll); tool point on the base axis with vertical (q1 free) and
    horizontal approach; nothing at all; straight and folded elbow; unreachable (too far, too
    close); off-plane approaches; approach normal to the arm's plane and n, o with no in-plane
    component (invalid); q5 defaults at the word limits; full-scale and most negative words."""
    arm = arm or load_arm()
    c = k.cfg
    fl, fu, fa = c.frac_length, c.frac_unit, c.frac_angle
    lo, hi, one = k.word_min, k.word_max, k.one_u
    rows = []

    def real(p, a, n=(0, 0, 0), o=(0, 0, 0), roll=False, q5d=0.0):
        rows.append((quantize(p, fl, c)[0], quantize(a, fu, c)[0], quantize(n, fu, c)[0],
                     quantize(o, fu, c)[0], roll, int(quantize(q5d, fa, c)[0])))

    def joints(q, roll=True):
        p, n, o, a = fk(arm, np.asarray(q, dtype=float))
        real(p, a, n, o, roll, 0.3)

    def words(p, a, n=(0, 0, 0), o=(0, 0, 0), roll=False, q5d=0):
        rows.append((np.array(p), np.array(a), np.array(n), np.array(o), roll, q5d))

    joints([0, -math.pi / 2, 0, -math.pi / 2, 0])
    joints([0, -math.pi / 2, 0, -math.pi / 2, 0], roll=False)
    real((0, 0, 20), (0, 0, -1))
    real((0, 0, 20), (0, 0, 1), (1, 0, 0), (0, 1, 0), True)
    real((0, 0, 15), (1, 0, 0))
    real((0, 0, 15), (0, -1, 0), (0, 0, 1), (1, 0, 0), True)
    words((0, 0, 0), (0, 0, 0), roll=True)
    joints([0.3, -1.0, 0.0, 0.2, 0.1])
    joints([-0.7, -0.5, math.pi, 0.4, -0.2])
    joints([1.2, -1.3, 1e-4, 0.3, 0.5])
    real((35, 0, 5), (1, 0, 0))
    real((0.5, 0.2, 5), (0, 0, -1))
    real((10, 10, 10), (0, 0, 1), (1, 0, 0), (0, 1, 0), True)
    real((12, 5, 8), (0.6, -0.8, 0.0))
    real((12, 0, 8), (0, 1, 0), (1, 0, 0), (0, 0, 1), True)
    real((12, 0, 8), (0.3, 0.9, -0.3), (0.2, 0.1, 0.9), (0.9, -0.3, 0.1), True)
    real((-7, -9, 3), (-0.5, -0.5, -0.7))
    real((12, 0, 8), (1, 0, 0), (0, 1, 0), (0, 1, 0), True)
    words((1 << fl, 2 << fl, 3 << fl), (0, 0, -one), q5d=hi)
    words((1 << fl, 2 << fl, 3 << fl), (0, 0, -one), q5d=lo)
    words((lo, lo, lo), (lo, lo, lo), (lo, lo, lo), (lo, lo, lo), True, lo)
    words((hi, hi, hi), (hi, hi, hi), (hi, hi, hi), (hi, hi, hi), True, hi)
    words((lo, hi, lo), (hi, lo, hi), (lo, hi, 0), (hi, lo, 0), True, lo)
    words((hi, lo, 0), (lo, 0, hi), (0, lo, lo), (lo, 0, hi), True, 1)
    words((lo, 0, hi), (0, lo, 0), (hi, hi, 0), (0, 0, lo), True, -1)
    words((0, lo, 0), (0, 0, lo), (lo, 0, 0), (0, lo, 0), True, 0)
    words((lo, lo, 0), (1, -1, 0), (1, 0, 0), (0, 1, 0), True, 0)
    words((1, 0, 0), (0, 0, 1), (0, 1, 0), (1, 0, 0), True, 0)
    words((-1, -1, -1), (-1, -1, -1), (-1, -1, -1), (-1, -1, -1), True, -1)
    rng = np.random.default_rng(99)
    for _ in range(6):
        def w():
            return int(rng.choice([lo, hi, 0, 1, -1, int(rng.integers(lo, hi, endpoint=True))]))
        words((w(), w(), w()), (w(), w(), w()), (w(), w(), w()), (w(), w(), w()),
              bool(rng.random() < 0.5), w())
    cols = [[] for _ in range(8)]
    for p, a, n, o, roll, q5d in rows:
        for branch in range(4):
            for col, value in zip(cols, (p, a, n, o, roll, q5d, branch >= 2, branch % 2 == 1)):
                col.append(value)
    return _pack(*(np.array(col) for col in cols))


def concat(*poses):
    return {key: np.concatenate([p[key] for p in poses]) for key in INPUTS}


def solve(k: Constants, poses, solve_batch=None) -> dict[str, np.ndarray]:
    """The model's outputs by field (``solve_batch``: ``model.solve_batch`` (default, the
    specification) or ``vector.solve_batch``)."""
    if solve_batch is None:
        from ik5r.firmware.model import solve_batch
    p = np.stack([poses["px"], poses["py"], poses["pz"]], axis=1)
    a = np.stack([poses["ax"], poses["ay"], poses["az"]], axis=1)
    n = np.stack([poses["nx"], poses["ny"], poses["nz"]], axis=1)
    o = np.stack([poses["ox"], poses["oy"], poses["oz"]], axis=1)
    q, status = solve_batch(k, p, a, n, o, poses["has_roll"].astype(bool),
                            poses["shoulder_back"].astype(bool), poses["elbow_down"].astype(bool),
                            poses["q5_default"])
    out = {f"q{j + 1}": np.asarray(q[:, j], dtype=np.int64) for j in range(5)}
    out["status"] = np.asarray(status, dtype=np.int64)
    return out
