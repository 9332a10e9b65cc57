"""Tables (markdown) and plots (PNG) of :mod:`ik5r.tools.seedtables` results, and docs/arms.md's update."""

from __future__ import annotations

from pathlib import Path

BEGIN, END = "<!-- arms:begin -->", "<!-- arms:end -->"


def _toz(t: dict) -> list[str]:
    lines = ["| target | ALO min (cm) | ALO mean (cm) | ALO max (cm) | ik5r numeric (cm) | ik5r CPU time (ms) | status |",
             "| --- | ---: | ---: | ---: | ---: | ---: | --- |"]
    for r in t["targets"]:
        lines.append(f"| {r['target']} | {r['alo_min_cm']:.2e} | {r['alo_mean_cm']:.2e} | {r['alo_max_cm']:.2e} "
                     f"| {r['error_cm']:.1e} | {r['cpu_ms']:.2f} | {r['status']} |")
    lines.append("")
    lines.append(f"ALO: 40 ants, 80 iterations, 30 runs per target, about 0.5 s per run (Toz, Table 3, Fig. 3b); "
                 f"ik5r: one call per target, median CPU time of {t['repeat']} calls on one core.")
    return lines


def _park(p: dict) -> list[str]:
    lines = ["| iteration | ik5r tool-point error (mm) | ik5r tool-direction error (rad) |",
             "| ---: | ---: | ---: |"]
    for r in p["trace"]:
        lines.append(f"| {r['iteration']} | {r['error_mm']:.2e} | {r['direction_rad']:.1e} |")
    lines.append("")
    lines.append(f"Park et al.: error {p['paper_error_5th']} at the 5th iteration, below 0.01 mm after 5 in every "
                 f"simulated case. As a welding path ({p['path_points']} points 10 mm apart, each started from "
                 f"the previous joints): {p['path_ok']}/{p['path_points']} ok, worst error "
                 f"{p['path_worst_error_mm']:.1e} mm; the first 10 mm step (warm start), error after iterations 0..5: "
                 + ", ".join(f"{e:.1e}" for e in p["path_first_step_error_mm"]) + " mm.")
    return lines


def _patil(p: dict) -> list[str]:
    lines = ["| method | targets | max error (cm) | RMS error (cm) | time per target (ms, CPU) |",
             "| --- | ---: | ---: | ---: | ---: |"]
    n = p["numeric"]
    lines.append(f"| ik5r numeric (position mode) | {p['targets']} ({n['ok']} ok) | {n['max_error_cm']:.1e} "
                 f"| {n['rms_error_cm']:.1e} | {n['ms_per_target']:.3g} |")
    for b in p["brute_force"]:
        lines.append(f"| brute force, {b['steps_per_joint']} steps per joint ({b['combinations']:,} combinations) "
                     f"| {b['targets']} | {b['max_error_cm']:.2f} | {b['rms_error_cm']:.2f} | {b['ms_per_target']:.0f} |")
    return lines


def _puma(p: dict) -> list[str]:
    hist = ", ".join(f"{k}: {v}" for k, v in p["histogram"].items())
    return [f"{p['poses']:,} random poses (joints uniform in the limits), pose mode, --all ({p['starts']} starts "
            f"per pose): solutions found per pose {{{hist}}}; all 8 for {p['all_8']:.1%} of the poses; worst "
            f"residuals {p['max_pos_err_cm']:.1e} cm, {p['max_rot_err_rad']:.1e} rad; "
            f"{p['ms_per_pose']:.1f} ms per pose (CPU)."]


def tables(result: dict) -> str:
    out = ["### Toz (seed 003): P1..P5 of Table 2, against Table 3", "", *_toz(result["toz"]), "",
           "### Park (seed 000): the welding move, 450 mm along y, tool direction kept", "", *_park(result["park"]), "",
           "### Patil (seed 001): a grid of targets, against brute force", "", *_patil(result["patil"]), "",
           "### PUMA 560: every solution", "", *_puma(result["puma560"])]
    return "\n".join(out)


def plots(result: dict, out: Path) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4))
    t = result["toz"]["targets"]
    x = range(len(t))
    for key, label in (("alo_max_cm", "ALO max"), ("alo_mean_cm", "ALO mean"), ("alo_min_cm", "ALO min")):
        axes[0].semilogy(x, [r[key] for r in t], "o--", label=label)
    axes[0].semilogy(x, [max(r["error_cm"], 1e-16) for r in t], "s-", label="ik5r numeric")
    axes[0].set_xticks(list(x), [r["target"] for r in t])
    axes[0].set_ylabel("position error (cm)")
    axes[0].set_title("Toz P1..P5 (Table 3)")
    axes[0].legend()
    tr = result["park"]["trace"]
    axes[1].semilogy([r["iteration"] for r in tr], [max(r["error_mm"], 1e-16) for r in tr], "s-", label="ik5r")
    axes[1].axhline(0.01, ls=":", color="k", label="Park: < 0.01 mm after 5")
    axes[1].plot([5], [result["park"]["paper_error_5th"]], "o", label="Park: 5th iteration")
    axes[1].set_xlabel("iteration")
    axes[1].set_ylabel("tool-point error (mm)")
    axes[1].set_title("Park welding move (450 mm along y)")
    axes[1].legend()
    hist = result["puma560"]["histogram"]
    axes[2].bar([int(k) for k in hist], list(hist.values()))
    axes[2].set_xlabel("distinct solutions found")
    axes[2].set_ylabel("poses")
    axes[2].set_title("PUMA 560, --all")
    fig.tight_layout()
    path = out / "arms_seed_tables.png"
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return [path]


def update_doc(doc: Path, text: str) -> None:
    """Replace the generated part of docs/arms.md (between the markers)."""
    body = doc.read_text()
    head, rest = body.split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    doc.write_text(f"{head}{BEGIN}\n\n*Generated by `python -m ik5r.tools.seedtables --record`; do not edit by hand.*\n\n"
                   f"{text}\n\n{END}{tail}")
