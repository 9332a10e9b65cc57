"""The one-screen terminal summary of the quantisation report (also ``make demo``'s): the
task-space errors (position, approach, n/o: max, RMS, p99.9 beside float32's, a verdict line
each), the joint errors in angle LSB, the status counts and the joint floor."""

from __future__ import annotations

from .quantisation import JOINTS, TASK_MEASURES, _ratio


def _g(x, digits=3):
    return "-" if x is None else f"{x:.{digits}g}"


def _task_lines(ts: dict) -> list[str]:
    fx, f32 = ts["fixed"], ts["float32"]
    lines = [f"{'task space vs target':<24}{'fixed':>12}{'float32':>12}{'fixed/f32':>11}"]
    for unit, (_, label) in TASK_MEASURES.items():
        u = "cm" if unit == "position_cm" else "rad"
        for stat in ("max", "rms", "p99.9"):
            r = _ratio(fx[unit][stat], f32[unit][stat])
            lines.append(f"{label + ' ' + stat + ' (' + u + ')':<24}{_g(fx[unit][stat]):>12}"
                         f"{_g(f32[unit][stat]):>12}{_g(r):>11}")
    return lines


def verdict_lines(ts: dict) -> list[str]:
    """One line per task-space measure: does fixed point beat float32 on its max and RMS?"""
    lines = []
    for unit, (_, label) in TASK_MEASURES.items():
        key = unit.split("_")[0]
        ratio = ts["ratio_fixed_over_float32"]
        lines.append(f"fixed beats float32 on max and RMS {label} error: "
                     f"{'YES' if ts['beats_float32'][key] else 'NO'} "
                     f"(ratios {_g(ratio[key + '_max'])}, {_g(ratio[key + '_rms'])})")
    return lines


def summary_text(fig: dict, out_dir=None) -> str:
    """The one-screen terminal summary of a figures dict (also for ``make demo``)."""
    ts, je = fig["task_space"], fig["joint_error"]
    f32 = ts["float32"]
    t = fig["timing"]
    rate = t.get("fixed_poses_per_s")
    lines = [
        f"ik5r quantisation report: config {fig['config']['name']}, arm {fig['arm']}, "
        f"N = {fig['vectors']:,}, seed {fig['seed']}, {_g(t.get('total_s'), 3)} s"
        + (f" (fixed solver {rate:,.0f} poses/s)" if rate else ""),
        "",
        *_task_lines(ts),
    ]
    lines += ["", f"joint error, max in angle LSB (2^-{fig['config']['frac_angle']} rad)"
              f"{'':9}" + "".join(f"{j:>9}" for j in JOINTS)]
    for comp, label in (("fixed_vs_exact", "fixed vs f64 exact"),
                        ("fixed_vs_exact_off_axis", "fixed vs f64 exact, rho>=axis"),
                        ("fixed_vs_quantised", "fixed vs f64 quantised"),
                        ("float32_vs_exact", "float32 vs f64 exact")):
        for key in ("all", "sin_q3_ge_1e-2"):
            row = je[comp][key]
            name = f"{label}, {'all' if key == 'all' else '|s3|>=1e-2'}"
            lines.append(f"  {name:<51}" + "".join(f"{_g(row[j]['max_lsb']):>9}" for j in JOINTS))
    fl = ts["fixed_flagged"]
    if fl["count"]:
        lines.append(f"{'position max, unflagged':<24}{_g(fl['unflagged_position_cm']['max']):>12}"
                     f"{'':>12}{_g(_ratio(fl['unflagged_position_cm']['max'], f32['position_cm']['max'])):>11}"
                     f"   ({fl['count']:,} flagged poses: max {_g(fl['position_cm_max'])} cm)")
    status = fig["status"]["fixed"]
    lines += ["", "fixed status: " + ", ".join(f"{k} {v:,}" for k, v in status.items())]
    floor = je["floor"]
    lines.append(f"joint error vs f64 on the same input words, |sin q3| >= 1e-3: max {_g(floor['max_rad'])} rad"
                 f" (floor {floor['bound_rad']:g}: {'met' if floor['met'] else 'NOT met'})")
    lines += verdict_lines(ts)
    if out_dir is not None:
        lines.append(f"report: {out_dir}/index.html")
    return "\n".join(lines)
