"""Figures of the quantisation report: fixed point and float32 against float64, on random poses.

Method (one pose = one random joint vector q, uniform in the joint limits, so reachable):

* the target pose (p, n, o, a) is FK(q) in float64; the float64 IK of it gives four branches and
  the one nearest q (wrapped) is *the* branch of the pose;
* the fixed-point solver (the vectorised bit-accurate model ``ik5r.firmware_model.vector``) solves that
  branch of the quantised pose; float32 (``reference.ik(dtype=float32)``, what a Nios II FPU
  computes) solves the float32-rounded pose, all four branches, and the same branch is taken;
* joint errors are wrapped differences against float64 on the same branch, (a) on the exact pose
  (end to end, input quantisation included) and (b) on the pose the solver actually saw (the
  dequantised words, or the float32-rounded values): the algorithm's own error;
* task-space errors are FK(solved q) in float64 against the target.

:func:`.sampling.compute` returns per-pose arrays (:class:`~.sampling.Samples`); :func:`figures`
reduces them to a dict of plain numbers; :func:`.summary.summary_text` renders the one-screen
terminal summary.
"""

from __future__ import annotations

import math

import numpy as np

from ik5r.core import reference as ref
from ik5r.core import status as st
from ik5r.core.arm import Arm
from ik5r.core.fxconfig import FixedConfig

from .sampling import COMPARISONS, JOINTS, Samples

#: Subsets of poses by |sin q3| (q2, q3 errors scale with 1 / |sin q3|): key -> lower bound.
SIN_Q3_BINS = {"all": 0.0, "sin_q3_ge_1e-3": 1e-3, "sin_q3_ge_1e-2": 1e-2, "sin_q3_ge_1e-1": 1e-1}
BIN_LABELS = {"all": "all poses", "sin_q3_ge_1e-3": "|sin q3| ≥ 1e-3",
              "sin_q3_ge_1e-2": "|sin q3| ≥ 1e-2", "sin_q3_ge_1e-1": "|sin q3| ≥ 1e-1"}
PERCENTILES = (50.0, 90.0, 99.0, 99.9, 99.99)
#: The joint-accuracy floor (issue 2): the solver's own error, against float64 on the same input
#: words and branch, where |sin q3| >= 1e-3.
JOINT_FLOOR_RAD = 1e-6
JOINT_FLOOR_BIN = "sin_q3_ge_1e-3"


# ---------------------------------------------------------------------------------------------
# Reduction to figures


def _f(x):
    """A plain JSON number (None for NaN / inf / missing)."""
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


def _max_rms(x) -> dict:
    x = np.abs(np.asarray(x, dtype=np.float64))
    if x.size == 0:
        return {"max": None, "rms": None, "mean": None}
    return {"max": _f(x.max()), "rms": _f(np.sqrt(np.mean(x * x))), "mean": _f(x.mean())}


def _distribution(x) -> dict:
    out = _max_rms(x)
    if np.size(x):
        for pct, value in zip(PERCENTILES, np.percentile(np.abs(x), PERCENTILES)):
            out[f"p{pct:g}"] = _f(value)
    return out


def _ratio(num, den):
    return _f(num / den) if num is not None and den else None


def _bin_masks(samples: Samples, extra=None) -> dict:
    masks = {key: samples.sin_q3 >= lo for key, lo in SIN_Q3_BINS.items()}
    return masks if extra is None else {key: m & extra for key, m in masks.items()}


def _input_lsb(cfg: FixedConfig):
    return 2.0**-cfg.frac_length, 2.0**-cfg.frac_unit, 2.0**-cfg.frac_angle


def _input_terms(arm: Arm, cfg: FixedConfig) -> dict:
    """Worst-case input quantisation: |dp|, dphi, |dw| (first order) and the base-axis radius.

    Near the base axis the plane of the arm turns by dq1 ~ (sqrt(2)/2 LSB_length) / rho; the approach,
    projected onto the turned plane, then loses a factor cos(dq1), which moves phi by up to dq1^2 / 4
    and the wrist centre by hypot(a4, d5) dq1^2 / 4. ``axis_radius_cm`` is the rho below which that
    second-order term exceeds the direct position term |dp|.
    """
    h_l, h_u, _ = _input_lsb(cfg)
    wrist_offset = math.hypot(arm.a[3], arm.d[4])
    dp = math.sqrt(3) / 2 * h_l
    dphi = math.sqrt(3) / 2 * h_u
    dq1_num = math.sqrt(2) / 2 * h_l
    return {"wrist_offset_cm": wrist_offset, "dp": dp, "dphi": dphi, "dw": dp + wrist_offset * dphi,
            "dq1_numerator_cm": dq1_num, "axis_radius_cm": dq1_num / math.sqrt(4 * dp / wrist_offset)}


def joint_figures(samples: Samples) -> dict:
    """Per comparison, per |sin q3| bin, per joint: max / RMS in rad and in angle LSB.

    ``*_off_axis`` repeat the end-to-end comparisons without the poses closer to the base axis than
    ``axis_radius_cm`` (there input quantisation turns the arm's plane, see :func:`_input_terms`).
    """
    lsb = 2.0**-samples.cfg.frac_angle
    axis_radius = _input_terms(samples.arm, samples.cfg)["axis_radius_cm"]
    off_axis = samples.radius >= axis_radius
    out = {"angle_lsb_rad": lsb, "axis_radius_cm": axis_radius,
           "near_axis_count": int(np.count_nonzero(~off_axis)),
           "bins": {key: {"min_abs_sin_q3": lo, "label": BIN_LABELS[key],
                          "count": int(np.count_nonzero(samples.sin_q3 >= lo)),
                          "off_axis_count": int(np.count_nonzero((samples.sin_q3 >= lo) & off_axis))}
                    for key, lo in SIN_Q3_BINS.items()}}
    plans = [(comp, comp, None) for comp in COMPARISONS]
    plans += [(f"{comp}_off_axis", comp, off_axis) for comp in ("fixed_vs_exact", "float32_vs_exact")]
    for name_out, comp, extra in plans:
        err = samples.joint_err[comp]
        out[name_out] = {}
        for key, mask in _bin_masks(samples, extra).items():
            per = {}
            for j, name in enumerate(JOINTS):
                s = _max_rms(err[mask, j])
                per[name] = {"max_rad": s["max"], "rms_rad": s["rms"],
                             "max_lsb": _ratio(s["max"], lsb), "rms_lsb": _ratio(s["rms"], lsb)}
            out[name_out][key] = per
    own = out["fixed_vs_quantised"][JOINT_FLOOR_BIN]
    worst = max((own[name]["max_rad"] for name in JOINTS if own[name]["max_rad"] is not None), default=None)
    out["floor"] = {"bound_rad": JOINT_FLOOR_RAD, "comparison": "fixed_vs_quantised",
                    "bin": JOINT_FLOOR_BIN, "max_rad": worst,
                    "met": worst is not None and worst <= JOINT_FLOOR_RAD}
    return out


def _conditioning_bins(samples: Samples, terms: dict, masks: dict) -> dict:
    """Per |sin q3| bin (poses off the base axis): the first-order bounds and the largest measured
    input effect and own error per joint."""
    arm = samples.arm
    a2, a3 = arm.a[1], arm.a[2]
    _, h_u, h_a = _input_lsb(samples.cfg)
    dw, dphi = terms["dw"], terms["dphi"]
    effect = np.abs(samples.joint_err["input_effect"])
    own = np.abs(samples.joint_err["fixed_vs_quantised"])
    bins = {}
    for key, lo in SIN_Q3_BINS.items():
        m = masks[key]
        entry = {"min_abs_sin_q3": lo, "off_axis_count": int(np.count_nonzero(m))}
        if lo > 0:
            entry["bound_q2_rad"] = 2 * dw / (a2 * lo)
            entry["bound_q3_rad"] = 2 * (a2 + a3) * dw / (a2 * a3 * lo)
            entry["bound_q4_rad"] = dphi + entry["bound_q2_rad"] + entry["bound_q3_rad"]
            entry["c3_rounding_q3_rad"] = h_u / 2 / lo
            for name in ("bound_q2_rad", "bound_q3_rad", "bound_q4_rad", "c3_rounding_q3_rad"):
                entry[name.replace("_rad", "_lsb")] = entry[name] / h_a
        entry["measured_input_effect_max_rad"] = {
            name: (_f(effect[m, j].max()) if m.any() else None) for j, name in enumerate(JOINTS)}
        entry["measured_fixed_own_max_rad"] = {
            name: (_f(own[m, j].max()) if m.any() else None) for j, name in enumerate(JOINTS)}
        bins[key] = entry
    return bins


def _bound_used(samples: Samples, terms: dict) -> dict:
    """Per-pose bounds (all poses, including the base-axis term), and the largest fraction of them
    the measured input effect used (<= 1 where the first-order analysis holds)."""
    arm = samples.arm
    a2, a3 = arm.a[1], arm.a[2]
    h_l, h_u, _ = _input_lsb(samples.cfg)
    effect = np.abs(samples.joint_err["input_effect"])
    s3 = np.maximum(samples.sin_q3, 1e-300)
    # q1 from the tool point and the approach together (docs/algorithm.md, "Joint 1 near the base
    # axis"): each rounded by up to sqrt(2)/2 LSB across the plane, weighed by its length in LSBs.
    t = arm.theta(samples.q)
    horizontal = np.abs(np.sin(t[:, 1] + t[:, 2] + t[:, 3]))          # |(ax, ay)| = |sin phi|
    dq1 = math.sqrt(2) / np.maximum(samples.radius / h_l + horizontal / h_u, 1e-300)
    dw_pose = terms["dp"] + terms["wrist_offset_cm"] * (terms["dphi"] + np.minimum(dq1, np.pi) ** 2 / 4)
    per_pose = {"q1": dq1, "q2": dw_pose / (a2 * s3), "q3": samples.wrist_dist * dw_pose / (a2 * a3 * s3)}
    return {name: _f(np.max(effect[:, JOINTS.index(name)] / bound)) for name, bound in per_pose.items()}


def _implied_wrist_error(samples: Samples) -> dict:
    """The solver's own error expressed as the wrist-centre error that would explain it (first
    order, poses away from the singular elbow): its internal length-format arithmetic acts like
    |dw|."""
    a2, a3 = samples.arm.a[1], samples.arm.a[2]
    h_l = _input_lsb(samples.cfg)[0]
    own = np.abs(samples.joint_err["fixed_vs_quantised"])
    away = samples.sin_q3 >= 1e-2
    implied = {"from_q2": own[away, 1] * a2 * samples.sin_q3[away] / h_l,
               "from_q3": own[away, 2] * a2 * a3 * samples.sin_q3[away] / samples.wrist_dist[away] / h_l}
    return {key: {"max": _max_rms(v)["max"], "rms": _max_rms(v)["rms"]} for key, v in implied.items()}


#: The first-order bounds of :func:`conditioning_figures`, as written in the report.
CONDITIONING_FORMULAE = {
    "q1": "dq1 <= sqrt(2) / (rho / LSB_length + |(ax, ay)| / LSB_unit)   (rho: tool point to base axis)",
    "q2": "dq2 <= |dw| / (a2 |sin q3|)",
    "q3": "dq3 <= D |dw| / (a2 a3 |sin q3|) <= (a2 + a3) |dw| / (a2 a3 |sin q3|)",
    "q4": "dq4 <= dphi + dq2 + dq3",
    "wrist": "|dw| <= sqrt(3)/2 LSB_length + hypot(a4, d5) (sqrt(3)/2 LSB_unit + dq1^2 / 4)",
    "axis": "rho_axis = (sqrt(2)/2 LSB_length) / sqrt(4 |dp| / hypot(a4, d5)): below it dq1^2/4 dominates |dw|",
    "c3_rounding": "solver's own: dq3 ~ (LSB_unit / 2) / |sin q3|",
    "bins": "bin bounds: at the bin's smallest |sin q3|, rho >= rho_axis (|dw| <= 2 x first-order term)",
}


def conditioning_figures(samples: Samples) -> dict:
    """First-order input-quantisation terms and how the measured input effect compares.

    The 2-link inverse Jacobian of the wrist centre w: dq2 = |dw| / (a2 |s3|),
    dq3 = D |dw| / (a2 a3 |s3|) (D = |w - joint 2 axis|); |dw| <= |dp| + hypot(a4, d5) |dphi|
    with |dp| <= sqrt(3)/2 LSB_length and |dphi| <= sqrt(3)/2 LSB_unit, plus hypot(a4, d5) dq1^2 / 4
    near the base axis. q1 (and q5 through it): dq1 <= sqrt(2) / (rho / LSB_length + |(ax, ay)| /
    LSB_unit), the point's and the approach's directions weighed by their lengths in LSBs. The solver's own
    rounding of cos q3 to the unit format adds LSB_unit / 2 / |s3| to q3.
    """
    h_l, h_u, h_a = _input_lsb(samples.cfg)
    terms = _input_terms(samples.arm, samples.cfg)
    off_axis = samples.radius >= terms["axis_radius_cm"]
    return {
        "lsb": {"length_cm": h_l, "unit": h_u, "angle_rad": h_a},
        "wrist_offset_cm": terms["wrist_offset_cm"],
        "max_input_error": {"position_cm": terms["dp"], "approach_rad": terms["dphi"],
                            "wrist_centre_cm": terms["dw"]},
        "axis_radius_cm": terms["axis_radius_cm"],
        "near_axis_count": int(np.count_nonzero(~off_axis)),
        "min_radius_cm": _f(samples.radius.min()),
        "min_abs_sin_q3": _f(samples.sin_q3.min()),
        "formulae": dict(CONDITIONING_FORMULAE),
        "bins": _conditioning_bins(samples, terms, _bin_masks(samples, off_axis)),
        "max_fraction_of_per_pose_bound_used": _bound_used(samples, terms),
        "solver_own_equivalent_wrist_error_lsb_length": _implied_wrist_error(samples),
        "input_wrist_error_bound_lsb_length": terms["dw"] / h_l,
    }


#: The task-space measures: key -> (Samples attribute, label).
TASK_MEASURES = {"position_cm": ("position_err", "position"), "approach_rad": ("approach_err", "approach"),
                 "orientation_rad": ("orientation_err", "n/o")}


def task_figures(samples: Samples) -> dict:
    out = {}
    for solver in ("fixed", "float32", "float64"):
        out[solver] = {unit: _distribution(getattr(samples, attr)[solver])
                       for unit, (attr, _) in TASK_MEASURES.items()}
    fx, f32 = out["fixed"], out["float32"]
    out["ratio_fixed_over_float32"] = {
        f"{unit.split('_')[0]}_{stat}": _ratio(fx[unit][stat], f32[unit][stat])
        for unit in TASK_MEASURES for stat in ("max", "rms", "p99.9")}
    for solver in ("fixed", "float32"):
        worst = {}
        for unit, (attr, _) in TASK_MEASURES.items():
            err = getattr(samples, attr)[solver]
            i = int(np.argmax(err))
            worst[unit] = {"radius_cm": _f(samples.radius[i]), "height_cm": _f(samples.height[i]),
                           "abs_sin_q3": _f(samples.sin_q3[i]), "error": _f(err[i])}
        out[solver]["worst_pose"] = worst
    # Poses the fixed solver flags (bits other than the harmless singular ones), e.g. a tool point
    # quantised onto the base axis: the plane then comes from the approach, the requested shoulder
    # branch may not exist and the solver clips and reports UNREACHABLE.
    flagged = (samples.status_fixed & ~(st.SINGULAR_ELBOW | st.SINGULAR_BASE)) != 0
    out["fixed_flagged"] = {
        "count": int(np.count_nonzero(flagged)),
        "position_cm_max": _f(samples.position_err["fixed"][flagged].max()) if flagged.any() else None,
        "unflagged_position_cm": _distribution(samples.position_err["fixed"][~flagged]),
        "unflagged_approach_rad": _distribution(samples.approach_err["fixed"][~flagged]),
    }
    # Per measure: fixed point at or below float32 on both the max and the RMS.
    out["beats_float32"] = {unit.split("_")[0]: bool(fx[unit]["max"] <= f32[unit]["max"]
                                                     and fx[unit]["rms"] <= f32[unit]["rms"])
                            for unit in TASK_MEASURES}
    out["fixed_beats_float32"] = bool(
        fx["position_cm"]["max"] < f32["position_cm"]["max"]
        and fx["position_cm"]["rms"] < f32["position_cm"]["rms"])
    return out


def status_figures(samples: Samples) -> dict:
    def counts(bits):
        values, num = np.unique(bits, return_counts=True)
        return {st.describe(v): int(c) for v, c in sorted(zip(values, num), key=lambda vc: -vc[1])}

    per_bit = {name: int(np.count_nonzero(samples.status_fixed & bit)) for bit, name in st.NAMES.items()}
    harmless = st.SINGULAR_ELBOW | st.SINGULAR_BASE
    return {
        "fixed": counts(samples.status_fixed),
        "fixed_per_bit": per_bit,
        "float64": counts(samples.status_float64),
        # Both have out_of_limits (every layer checks the arm's limits).
        "fixed_differs_from_float64": int(np.count_nonzero(samples.status_fixed != samples.status_float64)),
        "fixed_not_ok": int(np.count_nonzero(samples.status_fixed & ~harmless)),
        "input_words_saturated": int(samples.input_saturated),
    }


def figures(samples: Samples) -> dict:
    """Every figure of the quantisation report as a JSON-ready dict of plain numbers."""
    cfg, arm = samples.cfg, samples.arm
    return {
        "config": {"name": cfg.name, "source": cfg.source, "width": cfg.width,
                   "frac_length": cfg.frac_length, "frac_unit": cfg.frac_unit,
                   "frac_angle": cfg.frac_angle, "iterations": cfg.iterations,
                   "rounding": cfg.rounding},
        "arm": arm.name,
        "vectors": int(len(samples.q)),
        "seed": int(samples.seed),
        "timing": {key: _f(v) for key, v in samples.timing.items()},
        "branches": {"counts": [int(c) for c in np.bincount(samples.branch, minlength=ref.N_BRANCHES)],
                     "max_match_rad": _f(samples.branch_match_rad.max())},
        "joint_error": joint_figures(samples),
        "conditioning": conditioning_figures(samples),
        "task_space": task_figures(samples),
        "status": status_figures(samples),
    }
