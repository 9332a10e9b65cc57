"""The samples of the quantisation report (:mod:`.quantisation`): random joint vectors, their poses
solved in float64, in fixed point and in float32, as per-pose arrays (:class:`Samples`).

The method is in the docstring of :mod:`.quantisation`; :func:`compute` runs it chunk by chunk.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from functools import partial

import numpy as np

from ik5r.core import reference as ref
from ik5r.core import status as st
from ik5r.core.arm import Arm
from ik5r.core.fxconfig import FixedConfig, constants
from ik5r.firmware_model.poses import PoseBatch

JOINTS = ("q1", "q2", "q3", "q4", "q5")
#: Joint-error comparisons: key -> (solver, reference pose).
COMPARISONS = ("fixed_vs_exact", "fixed_vs_quantised", "float32_vs_exact", "float32_vs_quantised",
               "input_effect")
DEFAULT_CHUNK = 50_000


@dataclass
class Samples:
    """Per-pose arrays of a run (N poses)."""

    arm: Arm
    cfg: FixedConfig
    seed: int
    q: np.ndarray                 # (N, 5) the drawn joint vectors
    branch: np.ndarray            # (N,) float64 branch index matching q
    branch_match_rad: np.ndarray  # (N,) max |wrap(q64[branch] - q)|
    sin_q3: np.ndarray            # (N,) |sin q3| (float64 branch)
    radius: np.ndarray            # (N,) horizontal distance of the tool point from the base axis (cm)
    height: np.ndarray            # (N,) tool point z (cm)
    wrist_dist: np.ndarray        # (N,) distance joint 2 axis -> wrist centre (cm)
    joint_err: dict = field(default_factory=dict)   # COMPARISONS key -> (N, 5) signed rad
    position_err: dict = field(default_factory=dict)  # "fixed" / "float32" / "float64" -> (N,) cm
    approach_err: dict = field(default_factory=dict)  # same keys -> (N,) rad
    orientation_err: dict = field(default_factory=dict)  # same keys -> (N,) rad, n/o (see _no_error)
    status_fixed: np.ndarray = None   # (N,) fixed status bits
    status_float64: np.ndarray = None  # (N,) float64 status bits of the branch (exact pose)
    input_saturated: int = 0
    timing: dict = field(default_factory=dict)


def _unit_angle(u, v):
    """Angle (rad) between direction vectors (..., 3), robust for tiny angles."""
    cross = np.linalg.norm(np.cross(u, v), axis=-1)
    dot = np.sum(u * v, axis=-1)
    return np.arctan2(cross, dot)


def _take(q_all, branch):
    return q_all[np.arange(len(branch)), branch].astype(np.float64)


def _task_errors(arm, q, p, a):
    p_fk, _, _, a_fk = ref.fk(arm, q)
    return np.linalg.norm(p_fk - p, axis=-1), _unit_angle(a_fk, a)


def _no_error(arm, q, n, o):
    """The n/o error (rad): the larger of the angles between the solved and the target n and o
    (the tool's roll and direction together)."""
    _, n_fk, o_fk, _ = ref.fk(arm, q)
    return np.maximum(_unit_angle(n_fk, n), _unit_angle(o_fk, o))


def _float64_part(arm: Arm, q: np.ndarray, out: dict):
    """The float64 IK of FK(q): the branch nearest q and its errors; returns (p, n, o, a), q64."""
    count = len(q)
    p, n, o, a = ref.fk(arm, q)
    r64 = ref.ik(arm, p, a, n, o)
    diff = ref.wrap(r64.q - q[:, None, :])
    branch = np.argmin(np.sum(diff**2, axis=-1), axis=1)
    q64 = _take(r64.q, branch)
    out.update({
        "q": q, "branch": branch,
        "branch_match_rad": np.max(np.abs(diff[np.arange(count), branch]), axis=-1),
        "sin_q3": np.abs(np.sin(arm.theta(q64)[:, 2])),
        "radius": np.hypot(p[:, 0], p[:, 1]), "height": p[:, 2].copy(),
        "status_float64": r64.status[np.arange(count), branch],
    })
    t = arm.theta(q64)
    out["wrist_dist"] = np.sqrt(arm.a[1] ** 2 + arm.a[2] ** 2 + 2 * arm.a[1] * arm.a[2] * np.cos(t[:, 2]))
    pe, ae = _task_errors(arm, q64, p, a)
    out["position_float64"], out["approach_float64"] = pe, ae
    out["orientation_float64"] = _no_error(arm, q64, n, o)
    return (p, n, o, a), q64


def _fixed_part(arm: Arm, k, pose, q64, out: dict, timing: dict):
    """Fixed point: quantise, solve the branch, dequantise."""
    from ik5r.firmware_model.vector import solve_batch

    cfg = k.cfg
    p, n, o, a = pose
    branch = out["branch"]
    poses, input_status = PoseBatch.quantise(cfg, p, a, n, o)
    poses = poses.with_branch(branch)
    out["input_saturated"] = int(np.count_nonzero(input_status & st.SATURATED))
    t1 = time.perf_counter()
    q_a, status = poses.solve(partial(solve_batch, k))
    timing["fixed_solver_s"] = timing.get("fixed_solver_s", 0.0) + time.perf_counter() - t1
    q_fx = np.asarray(q_a, dtype=np.float64) * 2.0**-cfg.frac_angle
    out["status_fixed"] = np.asarray(status, dtype=np.int64)
    deq_l, deq_u = 2.0**-cfg.frac_length, 2.0**-cfg.frac_unit
    # float64 on the solver's own words, with the solver's arm plane (near the base axis the
    # quantised point alone would not give it; docs/algorithm.md, "Joint 1 near the base axis").
    r_deq = ref.ik(arm, poses.p * deq_l, poses.a * deq_u, poses.n * deq_u, poses.o * deq_u, confirm_tolerance_cm=None,
                   approach_plane=ref.fixed_plane(cfg))
    q64_deq = _take(r_deq.q, branch)
    out["fixed_vs_exact"] = ref.wrap(q_fx - q64)
    out["fixed_vs_quantised"] = ref.wrap(q_fx - q64_deq)
    out["input_effect"] = ref.wrap(q64_deq - q64)
    out["position_fixed"], out["approach_fixed"] = _task_errors(arm, q_fx, p, a)
    out["orientation_fixed"] = _no_error(arm, q_fx, n, o)


def _float32_part(arm: Arm, pose, q64, out: dict, timing: dict):
    """float32: the same algorithm on float32-rounded inputs."""
    p, n, o, a = pose
    branch = out["branch"]
    p32, a32, n32, o32 = (v.astype(np.float32) for v in (p, a, n, o))
    t1 = time.perf_counter()
    r32 = ref.ik(arm, p32, a32, n32, o32, dtype=np.float32, confirm_tolerance_cm=None)
    timing["float32_solver_s"] = timing.get("float32_solver_s", 0.0) + time.perf_counter() - t1
    q32 = _take(r32.q, branch)
    r64_32 = ref.ik(arm, p32.astype(np.float64), a32.astype(np.float64), n32.astype(np.float64),
                    o32.astype(np.float64), confirm_tolerance_cm=None)
    out["float32_vs_exact"] = ref.wrap(q32 - q64)
    out["float32_vs_quantised"] = ref.wrap(q32 - _take(r64_32.q, branch))
    out["position_float32"], out["approach_float32"] = _task_errors(arm, q32, p, a)
    out["orientation_float32"] = _no_error(arm, q32, n, o)


def _timed(timing: dict, key: str, t0: float) -> float:
    """Add the time since ``t0`` to ``timing[key]``; returns now."""
    now = time.perf_counter()
    timing[key] = timing.get(key, 0.0) + now - t0
    return now


def _chunk(arm: Arm, k, q: np.ndarray, timing: dict) -> dict:
    """Everything of one chunk of joint vectors."""
    out: dict = {}
    t0 = time.perf_counter()
    pose, q64 = _float64_part(arm, q, out)
    t0 = _timed(timing, "float64_s", t0)
    _fixed_part(arm, k, pose, q64, out, timing)
    t0 = _timed(timing, "fixed_s", t0)
    _float32_part(arm, pose, q64, out, timing)
    _timed(timing, "float32_s", t0)
    return out


def compute(arm: Arm, cfg: FixedConfig, vectors: int, seed: int = 0, *, chunk: int = DEFAULT_CHUNK,
            progress: bool = True) -> Samples:
    """Draw ``vectors`` joint vectors (uniform in the limits, ``seed``) and solve them all three ways."""
    from tqdm import tqdm

    if vectors < 1:
        raise ValueError("need at least one vector")
    start = time.perf_counter()
    k = constants(cfg, arm)
    q_all = ref.random_joints(arm, vectors, np.random.default_rng(seed))
    timing: dict = {}
    parts = []
    bounds = range(0, vectors, chunk)
    for lo in tqdm(bounds, desc=f"report {cfg.name}", unit="chunk", disable=not progress,
                   total=len(bounds)):
        parts.append(_chunk(arm, k, q_all[lo:lo + chunk], timing))

    def cat(key):
        return np.concatenate([part[key] for part in parts])

    samples = Samples(
        arm=arm, cfg=cfg, seed=seed, q=cat("q"), branch=cat("branch"),
        branch_match_rad=cat("branch_match_rad"), sin_q3=cat("sin_q3"), radius=cat("radius"),
        height=cat("height"), wrist_dist=cat("wrist_dist"),
        joint_err={key: cat(key) for key in COMPARISONS},
        position_err={s: cat(f"position_{s}") for s in ("fixed", "float32", "float64")},
        approach_err={s: cat(f"approach_{s}") for s in ("fixed", "float32", "float64")},
        orientation_err={s: cat(f"orientation_{s}") for s in ("fixed", "float32", "float64")},
        status_fixed=cat("status_fixed"), status_float64=cat("status_float64"),
        input_saturated=sum(part["input_saturated"] for part in parts),
    )
    timing["total_s"] = time.perf_counter() - start
    timing["fixed_poses_per_s"] = vectors / timing["fixed_solver_s"] if timing.get("fixed_solver_s") else None
    samples.timing = timing
    return samples
