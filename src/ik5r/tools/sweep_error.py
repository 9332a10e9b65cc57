"""The error figures of one sweep point: what the sweep table shows, and nothing more.

The same poses, arithmetic and figures as the quantisation report (``ik5r.tools.report.quantisation``:
q uniform in the joint limits, target FK(q) in float64, the float64 branch nearest q solved by the
vectorised bit-accurate model on the quantised pose, FK of the result against the target), for
the keys below; it skips the report's dequantised-reference solves, which a sweep does not show,
and keeps the float64 side and the float32 solver's position error (the plot's reference line),
the same for every config of a sweep, in the worker's memory from one point to the next.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from ik5r.core import reference as ref
from ik5r.core import status as st
from ik5r.core.arm import load_arm
from ik5r.core.fxconfig import FixedConfig, constants, quantize

JOINTS = ("q1", "q2", "q3", "q4", "q5")


@lru_cache(maxsize=2)
def _float_side(poses: int, seed: int, arm=None) -> dict:
    """Target poses, their float64 branch (``arm``; None: the arm of record), as the report draws
    them, and the float32 solver's largest position error on that branch."""
    from .report import sampling

    arm = arm or load_arm()
    q = ref.random_joints(arm, poses, np.random.default_rng(seed))
    p, n, o, a = ref.fk(arm, q)
    r64 = ref.ik(arm, p, a, n, o)
    diff = ref.wrap(r64.q - q[:, None, :])
    branch = np.argmin(np.sum(diff**2, axis=-1), axis=1)
    q64 = r64.q[np.arange(poses), branch].astype(np.float64)
    r32 = ref.ik(arm, *(v.astype(np.float32) for v in (p, a, n, o)), dtype=np.float32, confirm_tolerance_cm=None)
    position32, _ = sampling._task_errors(arm, r32.q[np.arange(poses), branch].astype(np.float64), p, a)
    return {"p": p, "n": n, "o": o, "a": a, "branch": branch, "q64": q64,
            "float32_position_err_max_cm": float(position32.max()),
            "sin_q3": np.abs(np.sin(arm.theta(q64)[:, 2])), "radius": np.hypot(p[:, 0], p[:, 1])}


def error_figures(cfg: FixedConfig, poses: int, seed: int, arm=None) -> dict:
    """Position, approach and joint error of the fixed-point IK at ``cfg`` against float64, on
    ``arm`` (None: the arm of record)."""
    from ik5r.firmware_model.vector import solve_batch

    from .report import quantisation as qz
    from .report import sampling

    arm = arm or load_arm()
    f = _float_side(poses, seed, arm)
    p_l, _ = quantize(f["p"], cfg.frac_length, cfg)
    a_u, n_u, o_u = (quantize(f[v], cfg.frac_unit, cfg)[0] for v in ("a", "n", "o"))
    branch = f["branch"]
    q_raw, status = solve_batch(constants(cfg, arm), p_l, a_u, n_u, o_u, np.ones(poses, dtype=bool),
                                branch >= 2, (branch & 1).astype(bool), np.zeros(poses, dtype=np.int64))
    q_fx = np.asarray(q_raw, dtype=np.float64) * 2.0**-cfg.frac_angle
    err = np.abs(ref.wrap(q_fx - f["q64"]))
    position, approach = sampling._task_errors(arm, q_fx, f["p"], f["a"])
    pos, app = qz._distribution(position), qz._distribution(approach)
    per_joint = {name: qz._max_rms(err[:, j]) for j, name in enumerate(JOINTS)}
    off_axis = f["radius"] >= qz._input_terms(arm, cfg)["axis_radius_cm"]
    conditioned = err[(f["sin_q3"] >= 1e-2) & off_axis]
    flagged = (np.asarray(status) & ~(st.SINGULAR_ELBOW | st.SINGULAR_BASE)) != 0
    return {
        "poses": poses, "seed": seed,
        "position_err_max_cm": pos["max"], "position_err_rms_cm": pos["rms"],
        "position_err_p99_cm": pos.get("p99"),
        "approach_err_max_rad": app["max"], "approach_err_rms_rad": app["rms"],
        "joint_err_max_rad": max(v["max"] for v in per_joint.values()),
        "joint_err_rms_rad": math.sqrt(sum(v["rms"] ** 2 for v in per_joint.values()) / len(JOINTS)),
        "joint_err_max_rad_conditioned": float(conditioned.max()) if conditioned.size else None,
        "joint_err_per_joint": {name: {"max_rad": v["max"], "rms_rad": v["rms"]}
                                for name, v in per_joint.items()},
        "fixed_flagged": int(np.count_nonzero(flagged)),
        "float32_position_err_max_cm": f["float32_position_err_max_cm"],
    }
