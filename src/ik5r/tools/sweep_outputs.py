"""The outputs of a sweep: the Pareto front, DIR/sweep.csv, sweep.json, the plots and index.html."""

from __future__ import annotations

import csv
from pathlib import Path

from ik5r.core.modes import Arch

CSV_FIELDS = (
    "name", "block", "arch", "width", "frac_length", "frac_unit", "frac_angle", "iterations",
    "guard_bits", "angle_guard_bits", "internal_guard_bits", "poses", "position_err_max_cm",
    "position_err_rms_cm", "joint_err_max_rad", "joint_err_rms_rad", "joint_err_max_rad_conditioned",
    "approach_err_max_rad", "fixed_flagged", "luts", "lut4", "carry", "ffs", "dsps", "brams",
    "lutram", "fits_device", "fits_ecp5_25k_est", "fmax_mhz", "latency_cycles", "cycles_per_result",
    "results_per_second", "device", "speed_grade", "pareto", "synth_seconds", "error_seconds",
)


# --- Pareto front --------------------------------------------------------------------

def pareto_flags(points: list[dict], x: str = "luts", y: str = "position_err_max_cm") -> list[bool]:
    """True for the points no other point of the same block beats on both ``x`` and ``y``."""
    flags = []
    for p in points:
        if p.get(x) is None or p.get(y) is None:
            flags.append(False)
            continue
        dominated = any(
            q is not p and q.get("block") == p.get("block") and q.get(x) is not None
            and q.get(y) is not None and q[x] <= p[x] and q[y] <= p[y] and (q[x] < p[x] or q[y] < p[y])
            for q in points)
        flags.append(not dominated)
    return flags


def _plots(points: list[dict], out_dir: Path, freq_floor: float | None) -> list[str]:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    groups = sorted({(p["block"], p["arch"]) for p in points})
    style = {"markers": {Arch.PIPELINED: "o", Arch.ITERATIVE: "s"},
             "colours": {g: f"C{i}" for i, g in enumerate(groups)}, "groups": groups}
    return [_error_vs_luts(points, out_dir, plt, style), _fmax_vs_width(points, out_dir, plt, style, freq_floor),
            _error_vs_width(points, out_dir, plt)]


def _error_vs_luts(points: list[dict], out_dir: Path, plt, style: dict) -> str:
    """Position error (max and RMS) against LUTs per block and arch, with each block's Pareto front."""
    markers, colours, groups = style["markers"], style["colours"], style["groups"]
    fig, ax = plt.subplots(figsize=(8, 5.5))
    for g in groups:
        pts = [p for p in points if (p["block"], p["arch"]) == g
               and p.get("luts") is not None and p.get("position_err_max_cm") is not None]
        if not pts:
            continue
        ax.scatter([p["luts"] for p in pts], [p["position_err_max_cm"] for p in pts],
                   marker=markers.get(g[1], "^"), color=colours[g], label=f"{g[0]} {g[1]} (max)")
        ax.scatter([p["luts"] for p in pts], [p["position_err_rms_cm"] for p in pts],
                   marker=markers.get(g[1], "^"), facecolors="none", edgecolors=colours[g],
                   alpha=0.6, label=f"{g[0]} {g[1]} (RMS)")
        for p in pts:
            ax.annotate(p["name"], (p["luts"], p["position_err_max_cm"]), fontsize=7,
                        xytext=(4, 3), textcoords="offset points")
    for block in sorted({p["block"] for p in points}):
        front = sorted((p for p in points if p["block"] == block and p.get("pareto")),
                       key=lambda p: p["luts"])
        if front:
            ax.step([p["luts"] for p in front], [p["position_err_max_cm"] for p in front],
                    where="post", color="k", lw=1, ls="--")
            ax.scatter([p["luts"] for p in front], [p["position_err_max_cm"] for p in front],
                       s=160, facecolors="none", edgecolors="k", lw=1.2,
                       label=f"Pareto front ({block})")
    f32 = [p.get("float32_position_err_max_cm") for p in points if p.get("float32_position_err_max_cm")]
    if f32:
        ax.axhline(max(f32), color="grey", ls=":", lw=1, label="float32 (max)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("LUT4 sites (TRELLIS_COMB after P&R)")
    ax.set_ylabel("task-space position error (cm)")
    ax.set_title("IK position error against area")
    ax.grid(True, which="both", alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    fig.savefig(out_dir / "error_vs_luts.png", dpi=120)
    plt.close(fig)
    return "error_vs_luts.png"


def _fmax_vs_width(points: list[dict], out_dir: Path, plt, style: dict, freq_floor: float | None) -> str:
    """Fmax against word width per block and arch."""
    markers, colours, groups = style["markers"], style["colours"], style["groups"]
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for g in groups:
        pts = sorted((p for p in points if (p["block"], p["arch"]) == g and p.get("fmax_mhz")),
                     key=lambda p: (p["width"], p["iterations"]))
        if pts:
            ax.plot([p["width"] for p in pts], [p["fmax_mhz"] for p in pts],
                    marker=markers.get(g[1], "^"), color=colours[g], label=f"{g[0]} {g[1]}")
    if freq_floor:
        ax.axhline(freq_floor, color="grey", ls=":", lw=1, label=f"{freq_floor:g} MHz")
    ax.set_xlabel("word width (bits)")
    ax.set_ylabel("Fmax (MHz)")
    device = next((f"{p['target']} {p['device']} speed {p['speed_grade']}" for p in points
                   if p.get("device")), "")
    ax.set_title(f"Fmax against word width {device}")
    ax.grid(True, alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out_dir / "fmax_vs_width.png", dpi=120)
    plt.close(fig)
    return "fmax_vs_width.png"


def _error_vs_width(points: list[dict], out_dir: Path, plt) -> str:
    """Position error against word width, one line per internal guard bits (and iteration rule)."""
    fig, ax = plt.subplots(figsize=(7, 4.5))
    series = {}
    for p in points:
        if p.get("position_err_max_cm") is None:
            continue
        rule = "" if p["iterations"] == p["width"] else f", {p['iterations'] - p['width']:+d} iterations"
        series.setdefault((p.get("internal_guard_bits", 0), rule), {})[p["width"]] = p["position_err_max_cm"]
    for (guard, rule), by_width in sorted(series.items()):
        widths = sorted(by_width)
        ax.plot(widths, [by_width[w] for w in widths], marker="o", ms=3,
                label=f"{guard} internal guard bits{rule}")
    ax.set_yscale("log")
    ax.set_xlabel("word width (bits)")
    ax.set_ylabel("max position error (cm)")
    ax.set_title("IK position error against word width")
    ax.grid(True, which="both", alpha=0.3)
    if series:
        ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(out_dir / "error_vs_width.png", dpi=120)
    plt.close(fig)
    return "error_vs_width.png"


CAPTIONS = {"error_vs_luts.png": "position error against LUTs", "fmax_vs_width.png": "Fmax against word width",
            "error_vs_width.png": "position error against word width"}


def _html(points: list[dict], meta: dict, out_dir: Path, images: list[str]) -> None:
    from .report.html import Section, image, para, render_page, table

    header = ["point", "block", "arch", "width", "iter", "internal guard", "pos max (cm)", "pos RMS (cm)",
              "joint max (rad)", "joint RMS (rad)", "LUTs", "FFs", "DSP", "Fmax (MHz)",
              "results/s", "Pareto"]
    rows = [[p["name"], p["block"], p["arch"], p["width"], p["iterations"], p.get("internal_guard_bits"),
             p.get("position_err_max_cm"), p.get("position_err_rms_cm"),
             p.get("joint_err_max_rad"), p.get("joint_err_rms_rad"), p.get("luts"), p.get("ffs"),
             p.get("dsps"), p.get("fmax_mhz"), p.get("results_per_second"),
             "yes" if p.get("pareto") else ""] for p in points]
    sections = [
        Section("points", "Sweep points", table(header, rows)),
        Section("plots", "Plots", "".join(image(name, CAPTIONS[name]) for name in images)),
        Section("rule", "Config rule", para(
            "frac.length = w − 8, frac.unit = w − 2, frac.angle = w − 3, iterations = w, "
            "guard_bits = round(log2 w) − 1, angle_guard_bits = 3, rounding nearest "
            "(reproduces configs/q18, q24, q32); --guard-bits sets ik.internal_guard_bits.")),
    ]
    (out_dir / "index.html").write_text(render_page("ik5r word-length sweep", sections,
                                                    {k: v for k, v in meta.items()
                                                     if isinstance(v, (str, int, float))}))


def write_outputs(record, out_dir: Path, freq_floor: float | None = 150.0):
    """DIR/sweep.csv, the record (:meth:`~ik5r.tools.sweep_record.SweepRecord.write`), the plots
    and index.html of a sweep's :class:`~ik5r.tools.sweep_record.SweepRecord` (its points get
    their ``pareto`` flag first)."""
    points, meta = list(record.points), record.meta
    out_dir.mkdir(parents=True, exist_ok=True)
    for p, flag in zip(points, pareto_flags(points)):
        p["pareto"] = flag
    with open(out_dir / "sweep.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=CSV_FIELDS, extrasaction="ignore")
        writer.writeheader()
        for p in points:
            writer.writerow({k: ("" if p.get(k) is None else p.get(k)) for k in CSV_FIELDS})
    record.write(out_dir)
    if any(p.get("luts") is not None for p in points):
        images = _plots(points, out_dir, freq_floor)
    else:   # an error-only sweep (--no-synth): no area or Fmax to plot
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        images = [_error_vs_width(points, out_dir, plt)]
    _html(points, meta, out_dir, images)
    return images


