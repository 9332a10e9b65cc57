"""Assemble the quantisation report: figures -> sections (tables + plots) -> DIR/index.html + report.json."""

from __future__ import annotations

import datetime as _dt
from pathlib import Path

from ik5r.core.arm import Arm, load_arm
from ik5r.core.fxconfig import FixedConfig, load_config
from ik5r.core.modes import Block, CoreArch

from . import hardware, plots, provenance
from . import worst as worst_poses
from .html import Section, esc, fmt, image, para, table, write_report
from .quantisation import (
    BIN_LABELS,
    PERCENTILES,
    SIN_Q3_BINS,
    TASK_MEASURES,
    figures,
)
from .sampling import JOINTS, Samples, compute
from .summary import summary_text


def _where(source: str) -> str:
    """A shipped config by its place in the repository, any other by its path."""
    from ik5r.core.fxconfig import config_dir

    path = Path(source)
    return f"shipped: configs/{path.name}" if path.parent == config_dir() else source


def _overview(fig: dict, prov: dict) -> Section:
    cfg, t = fig["config"], fig["timing"]
    ts = fig["task_space"]
    verdict = ts["fixed_beats_float32"]
    rows = [
        ("config", f"{cfg['name']} ({_where(cfg['source'])})"),
        ("word width", cfg["width"]),
        ("fraction bits: length / unit / angle", f"{cfg['frac_length']} / {cfg['frac_unit']} / {cfg['frac_angle']}"),
        ("LSB: length (cm) / unit / angle (rad)",
         " / ".join(fmt(2.0**-cfg[k]) for k in ("frac_length", "frac_unit", "frac_angle"))),
        ("CORDIC iterations, rounding", f"{cfg['iterations']}, {cfg['rounding']}"),
        ("arm", fig["arm"]),
        ("poses (N)", fig["vectors"]),
        ("seed", fig["seed"]),
        ("branches (front/up, front/down, back/up, back/down)", " / ".join(f"{c:,}" for c in fig["branches"]["counts"])),
        ("max |q64 − q| of the matched branch (rad)", fig["branches"]["max_match_rad"]),
        ("total run time (s)", t.get("total_s")),
        ("fixed solver time (s) / poses per s", f"{fmt(t.get('fixed_solver_s'))} / {fmt(t.get('fixed_poses_per_s'))}"),
        ("float32 solver time (s)", t.get("float32_solver_s")),
    ]
    html_ = [
        para("N joint vectors q are drawn uniformly in the joint limits (so every pose is reachable); "
             "the target pose is FK(q) in float64. The float64 IK branch nearest q is <em>the</em> branch "
             "of the pose; the fixed-point solver (vectorised bit-accurate model of the C/HDL) and float32 "
             "(the same algorithm in single precision, what a Nios II FPU computes) solve that branch, and "
             "are compared with float64 on the same branch."),
        table(("setting", "value"), rows, caption="Setup"),
        para(f"Fixed point beats float32 on both max and RMS position error: "
             f"<span class=\"{'ok' if verdict else 'bad'}\">{'yes' if verdict else 'no'}</span> "
             f"(fixed/float32 ratios: max {fmt(ts['ratio_fixed_over_float32']['position_max'])}, "
             f"RMS {fmt(ts['ratio_fixed_over_float32']['position_rms'])})."),
        table(("provenance", "value"), provenance.rows(prov), caption="Provenance"),
    ]
    data = {k: fig[k] for k in ("config", "arm", "vectors", "seed", "timing", "branches")}
    data["provenance"] = prov
    data["fixed_beats_float32"] = verdict
    return Section("overview", "Overview", "\n".join(html_), data)


def _joint_table(fig: dict, solver_comp: str, f32_comp: str, caption: str) -> str:
    je = fig["joint_error"]
    rows = []
    for key in SIN_Q3_BINS:
        for j in JOINTS:
            fx, f32 = je[solver_comp][key][j], je[f32_comp][key][j]
            ratio = fx["max_rad"] / f32["max_rad"] if fx["max_rad"] is not None and f32["max_rad"] else None
            rows.append((f"{BIN_LABELS[key]} ({je['bins'][key]['count']:,}): {j}",
                         fx["max_rad"], fx["rms_rad"], fx["max_lsb"], fx["rms_lsb"],
                         f32["max_rad"], f32["rms_rad"], f32["max_lsb"], f32["rms_lsb"], ratio))
    header = ("poses: joint", "fixed max (rad)", "fixed RMS (rad)", "fixed max (LSB)", "fixed RMS (LSB)",
              "float32 max (rad)", "float32 RMS (rad)", "float32 max (LSB)", "float32 RMS (LSB)",
              "max fixed/float32")
    return table(header, rows, caption=caption)


def _off_axis_part(fig: dict) -> str:
    """Table (a') without the poses near the base axis, or one line when there are none."""
    je = fig["joint_error"]
    where = (f"within ρ_axis = {fmt(je['axis_radius_cm'])} cm of the base axis (there input quantisation "
             f"turns the arm's plane: q1, q5 and, at second order, q2-q4 follow 1/ρ)")
    if je["near_axis_count"] == 0:
        return para(f"(a′) No pose lies {where}, so table (a) holds without them as it stands.")
    return _joint_table(fig, "fixed_vs_exact_off_axis", "float32_vs_exact_off_axis",
                        f"(a′) End to end without the {je['near_axis_count']:,} poses {where}")


def _joint_section(fig: dict, img: str) -> Section:
    lsb = fig["joint_error"]["angle_lsb_rad"]
    html_ = [
        para(f"Wrapped joint-angle differences against float64 on the same branch. LSB = one step of the "
             f"angle format, 2<sup>−{fig['config']['frac_angle']}</sup> rad = {fmt(lsb)} rad (float32 "
             f"errors are expressed in the same unit). Poses are binned by |sin q3| because q2/q3 errors "
             f"scale with 1/|sin q3| near the straight or folded elbow (see the conditioning section)."),
        _joint_table(fig, "fixed_vs_exact", "float32_vs_exact",
                     "(a) End to end: against float64 on the exact pose (input quantisation included)"),
        _off_axis_part(fig),
        _joint_table(fig, "fixed_vs_quantised", "float32_vs_quantised",
                     "(b) The algorithm's own error: against float64 on the pose the solver saw "
                     "(dequantised words for fixed, float32-rounded values for float32)"),
        para(f"Joint floor: the fixed solver's own error (b) where |sin q3| ≥ 1e-3 is at most "
             f"{fmt(fig['joint_error']['floor']['max_rad'])} rad over all joints, against a floor of "
             f"{fmt(fig['joint_error']['floor']['bound_rad'])} rad: <span class=\"{'ok' if fig['joint_error']['floor']['met'] else 'bad'}\">"
             f"{'met' if fig['joint_error']['floor']['met'] else 'not met'}</span>."),
        image(img, "Per-joint |error| histograms (log-log), fixed and float32 against float64"),
    ]
    data = fig["joint_error"]
    return Section("joint_error", "Joint-space error against float64", "\n".join(html_), data, (img,))


def _conditioning_section(fig: dict, img: str) -> Section:
    c = fig["conditioning"]
    lsb, mx = c["lsb"], c["max_input_error"]
    f = c["formulae"]
    html_ = [
        para("Quantising the input pose moves the target by up to half an LSB per component; the closed-form "
             "IK maps that through its inverse Jacobian. The planar 2-link part (joints 2, 3 reaching the "
             "wrist centre w) has determinant a2·a3·sin q3, so its conditioning diverges at the straight or "
             "folded elbow, and q1 (with q5, which is measured relative to the arm's plane) is conditioned by "
             "1/ρ, the distance of the tool point from the base axis. First-order bounds:"),
        "<pre>" + esc("\n".join(f"{k:>12}: {v}" for k, v in f.items())) + "</pre>",
        table(("quantity", "value"), [
            ("LSB length (cm)", lsb["length_cm"]), ("LSB unit vector", lsb["unit"]),
            ("LSB angle (rad)", lsb["angle_rad"]),
            ("max input position error |dp| (cm)", mx["position_cm"]),
            ("max approach error dphi (rad)", mx["approach_rad"]),
            ("wrist offset hypot(a4, d5) (cm)", c["wrist_offset_cm"]),
            ("max wrist-centre error |dw| (cm)", mx["wrist_centre_cm"]),
            ("smallest |sin q3| drawn", c["min_abs_sin_q3"]),
            ("smallest ρ drawn (cm)", c["min_radius_cm"]),
            ("ρ_axis: below it the dq1²/4 term dominates |dw| (cm)", c["axis_radius_cm"]),
            ("poses with ρ < ρ_axis", c["near_axis_count"]),
        ], caption="Input quantisation (fixed point)"),
    ]
    rows = []
    for key, b in c["bins"].items():
        if SIN_Q3_BINS[key] == 0:
            continue
        me, own = b["measured_input_effect_max_rad"], b["measured_fixed_own_max_rad"]
        rows.append((f"{BIN_LABELS[key]}, ρ ≥ ρ_axis ({b['off_axis_count']:,})", b["bound_q2_rad"], me["q2"], b["bound_q3_rad"],
                     me["q3"], b["bound_q4_rad"], me["q4"], b["c3_rounding_q3_rad"], own["q3"]))
    html_.append(table(("poses", "q2 bound (rad)", "q2 input effect max", "q3 bound", "q3 input effect max",
                        "q4 bound", "q4 input effect max", "q3 c3-rounding term", "q3 fixed own error max"),
                       rows, caption="Input-quantisation bounds per |sin q3| bin (poses at least ρ_axis from "
                                     "the base axis) against the measured input effect (float64 on the dequantised pose − float64 on "
                                     "the exact pose), and the solver's own q3 error"))
    used = c["max_fraction_of_per_pose_bound_used"]
    html_.append(para("Largest fraction of the per-pose bound (all poses, base-axis term included) used by "
                      "the measured input effect (≤ 1 where the analysis holds): " + ", ".join(f"{k} {fmt(v)}" for k, v in used.items())
                      + "."))
    eq = c["solver_own_equivalent_wrist_error_lsb_length"]
    html_.append(para(
        "The solver's own error (b) follows the same law: its wrist centre is computed in the length format "
        "(isqrt, CORDIC rotation, subtractions), so rounding there acts like a wrist-centre error. Expressed "
        "as the |dw| that would explain it (poses with |sin q3| ≥ 1e-2): "
        f"from q2 max {fmt(eq['from_q2']['max'])} / RMS {fmt(eq['from_q2']['rms'])} LSB<sub>length</sub>, "
        f"from q3 max {fmt(eq['from_q3']['max'])} / RMS {fmt(eq['from_q3']['rms'])} LSB<sub>length</sub> "
        f"(input quantisation bound: {fmt(c['input_wrist_error_bound_lsb_length'])} LSB<sub>length</sub>). "
        "The c3 rounding term (unit format) is much smaller."))
    html_.append(para(
        "Task space is well conditioned (FK does not divide by sin q3), so the position error stays at a few "
        "length LSB even where the joint errors are large. The approach direction, however, depends on q1, "
        "and q1 is conditioned by 1/ρ: near the base axis a sub-LSB move of the tool point turns the arm's "
        "plane (a 5R arm can only reach approaches in that plane), so the largest approach errors sit at small ρ."))
    html_.append(image(img, "Joint error of q2, q3, q4 against |sin q3| (log-log) with the first-order bound"))
    return Section("conditioning", "Why: input-quantisation conditioning", "\n".join(html_), c, (img,))


def _task_section(fig: dict, imgs: tuple[str, str, str]) -> Section:
    ts = fig["task_space"]
    stats = ["max", "rms", "mean"] + [f"p{p:g}" for p in PERCENTILES]
    parts = [para("FK (float64) of the solved joint vector against the target pose: Euclidean tool-point "
                  "error and the angle between the approach vectors. float64 is the reference's own "
                  "round-trip floor.")]
    captions = {"position_cm": "Position error (cm)", "approach_rad": "Approach-direction error (rad)",
                "orientation_rad": "n/o error (rad): the larger angle between solved and target n, o"}
    r = ts["ratio_fixed_over_float32"]
    for unit, (_, name) in TASK_MEASURES.items():
        rows = []
        for s in stats:
            fx, f32, f64 = (ts[k][unit].get(s) for k in ("fixed", "float32", "float64"))
            rows.append((s, fx, f32, f64, fx / f32 if fx is not None and f32 else None))
        parts.append(table(("statistic", "fixed", "float32", "float64", "fixed/float32"), rows,
                           caption=captions[unit]))
        key = unit.split("_")[0]
        verdict = ts["beats_float32"][key]
        parts.append(para(f"Fixed/float32 ratio of the {name} error: max {fmt(r[key + '_max'])}, RMS "
                          f"{fmt(r[key + '_rms'])}, p99.9 {fmt(r[key + '_p99.9'])} &mdash; fixed point beats "
                          f"float32 on max and RMS: <span class=\"{'ok' if verdict else 'bad'}\">"
                          f"{'yes' if verdict else 'no'}</span>."))
    worst_rows = []
    for solver in ("fixed", "float32"):
        for unit in TASK_MEASURES:
            w = ts[solver]["worst_pose"][unit]
            worst_rows.append((f"{solver}: max {unit.split('_')[0]} error", w["error"], w["radius_cm"],
                               w["height_cm"], w["abs_sin_q3"]))
    fl = ts["fixed_flagged"]
    parts.append(para(
        f"{fl['count']:,} poses carry a fixed status bit other than the harmless singular ones (largest "
        f"position error among them {fmt(fl['position_cm_max'])} cm); without them the fixed position error "
        f"is at most {fmt(fl['unflagged_position_cm']['max'])} cm (RMS {fmt(fl['unflagged_position_cm']['rms'])}) "
        f"and the approach error at most {fmt(fl['unflagged_approach_rad']['max'])} rad. A tool point that "
        "quantises onto the base axis takes the arm's plane from the approach, so the requested shoulder "
        "branch may not exist: the solver clips and flags it unreachable (the float64 reference does the same "
        "on the quantised pose). The tables above include every pose."))
    parts.append(table(("pose", "error", "ρ (cm)", "z (cm)", "|sin q3|"), worst_rows,
                       caption="Where the worst errors are"))
    parts.append(image(imgs[0], "Histograms of position and approach error, fixed vs float32 (log-log)"))
    parts.append(image(imgs[1], "Position error against reach and height (hexbin, subsampled)"))
    parts.append(image(imgs[2], "Approach error against the distance from the base axis (log-log, subsampled)"))
    return Section("task_space", "Task-space error", "\n".join(parts), ts, imgs)


def _status_section(fig: dict) -> Section:
    s = fig["status"]
    names = list(dict.fromkeys(list(s["fixed"]) + list(s["float64"])))
    rows = [(name, s["fixed"].get(name, 0), s["float64"].get(name, 0)) for name in names]
    per_bit = [(name, count) for name, count in s["fixed_per_bit"].items()]
    html_ = [
        para("Status bits of the solved branch (ik5r.core.status.describe); singular_elbow flags |sin q3| ≤ "
             "ik.singular_sin_q3 and is harmless; float64 also reports out_of_limits (never set here)."),
        table(("status", "fixed", "float64 (same branch)"), rows, caption="Status combinations"),
        table(("bit", "fixed poses with the bit set"), per_bit, caption="Fixed status per bit"),
        table(("check", "poses"), [
            ("fixed status differs from float64", s["fixed_differs_from_float64"]),
            ("fixed status with a bit other than the singular ones", s["fixed_not_ok"]),
            ("poses with a saturated input word", s["input_words_saturated"]),
        ]),
    ]
    return Section("status", "Status counts", "\n".join(html_), s)


def quantisation_sections(samples: Samples, fig: dict, out_dir, prov: dict | None = None) -> list[Section]:
    """The quantisation report's sections; draws its PNGs into ``out_dir``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    img_joint = plots.joint_histograms(samples, out_dir)
    img_sin = plots.joint_vs_sin_q3(samples, out_dir, fig["conditioning"])
    img_pos = plots.position_histogram(samples, out_dir)
    img_ws = plots.position_vs_workspace(samples, out_dir)
    img_app = plots.approach_vs_radius(samples, out_dir)
    return [
        _overview(fig, prov or provenance.provenance(samples.cfg)),
        _task_section(fig, (img_pos, img_ws, img_app)),
        _joint_section(fig, img_joint),
        _conditioning_section(fig, img_sin),
        _status_section(fig),
    ]


def _glance(fig: dict, sections: list[Section]) -> Section:
    """The story in one table: accuracy verdicts, bit accuracy, the IK core's hardware figures."""
    ts, floor = fig["task_space"], fig["joint_error"]["floor"]
    by_key = {s.key: s.data for s in sections}

    def verdict(ok):
        return f'<span class="{"ok" if ok else "bad"}">{"yes" if ok else "no"}</span>'

    rows = [(f"fixed point beats float32 on max and RMS {name} error",
             f"{verdict(ts['beats_float32'][unit.split('_')[0]])} (max {fmt(ts['fixed'][unit]['max'])} "
             f"{unit.split('_')[1]} against {fmt(ts['float32'][unit]['max'])}, RMS "
             f"{fmt(ts['fixed'][unit]['rms'])} against {fmt(ts['float32'][unit]['rms'])})")
            for unit, (_, name) in TASK_MEASURES.items()]
    rows.append(("joint error ≤ 1e-6 rad against float64 on the same words, |sin q3| ≥ 1e-3",
                 f"{verdict(floor['met'])} (max {fmt(floor['max_rad'])} rad)"))
    data = {"fixed_beats_float32": ts["fixed_beats_float32"], "beats_float32": ts["beats_float32"],
            "joint_floor_met": floor["met"]}
    total = by_key.get("bit_accuracy", {}).get("total_mismatches")
    if total is not None:
        rows.append(("C, scalar model, vectorised model and HDL agree on every bit",
                     f"{verdict(total == 0)} ({total:,} mismatching items)"))
        data["total_mismatches"] = total
    core = next((r for r in by_key.get("hardware", {}).get("rows", [])
                 if r["block"] == Block.IK and r["arch"] == CoreArch.PIPELINED), None)
    if core:
        rows.append(("pipelined IK core (committed record)",
                     f"{fmt(core['fmax_mhz'])} MHz on {esc(core['device'])}, latency {core['latency_cycles']} "
                     f"cycles, {core['cycles_per_pose']} cycle/pose, {fmt(core['lut4_sites'])} LUT4, "
                     f"{fmt(core['dsps'])} DSP, {fmt(core['brams'])} BRAM"))
        data["core"] = core
    body = "<table>" + "".join(f"<tr><th>{esc(k)}</th><td style=\"text-align:left\">{v}</td></tr>"
                               for k, v in rows) + "</table>"
    return Section("glance", "At a glance", body, data)


def build_report(out_dir, vectors: int = 1_000_000, config: FixedConfig | str | None = None,
                 arm: Arm | str | None = None, seed: int = 0, *, progress: bool = True,
                 extra_sections: list[Section] | None = None, worst: int = 20,
                 simulators: bool = False, front_sections: list[Section] | None = None):
    """Run the quantisation report into ``out_dir``; returns (report JSON dict, summary text).

    Sections: the overview, ``front_sections`` (e.g. bit accuracy), the hardware records of the
    config, the quantisation figures, the N = ``worst`` worst poses of each measure (CSV), then
    ``extra_sections`` (e.g. the generated files).
    """
    cfg = config if isinstance(config, FixedConfig) else load_config(config)
    arm_ = arm if isinstance(arm, Arm) else load_arm(arm)
    samples = compute(arm_, cfg, vectors, seed, progress=progress)
    fig = figures(samples)
    prov = provenance.provenance(cfg, simulators=simulators)
    overview, *figure_sections = quantisation_sections(samples, fig, out_dir, prov)
    sections = [overview, *(front_sections or []), hardware.section(cfg), *figure_sections,
                worst_poses.section(samples, out_dir, worst), *(extra_sections or [])]
    sections.insert(0, _glance(fig, sections))
    meta = {"report": "quantisation", "config": cfg.name, "arm": arm_.name, "vectors": vectors,
            "seed": seed, "total_s": round(fig["timing"]["total_s"], 3),
            "generated_utc": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
            "ik5r": prov["package_version"], "git_commit": prov["git_commit"],
            "config_hash": prov["config_hash"], "provenance": prov}
    doc = write_report(out_dir, sections, meta, title=f"ik5r quantisation report: {cfg.name} on {arm_.name}")
    return doc, summary_text(fig, out_dir)
