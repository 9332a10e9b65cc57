"""``ik5r report --configs q18,q24,q32,q32w``: one page comparing configs, error against bits.

Each config gets the quantisation report's figures on the same poses (same N and seed), one row
per config, next to its committed hardware record; ``error_vs_bits.png`` plots the error against
the word width. Writes DIR/index.html and DIR/report.json (``{"meta", "configs": [row, ...]}``).
"""

from __future__ import annotations

import datetime as _dt
import json
from pathlib import Path

from ik5r.core.arm import Arm, load_arm
from ik5r.core.fxconfig import load_config
from ik5r.core.modes import Block, CoreArch

from . import hardware, provenance
from .html import Section, image, jsonable, para, render_page, table
from .quantisation import figures
from .sampling import compute


def config_row(fig: dict, cfg) -> dict:
    ts, je = fig["task_space"], fig["joint_error"]
    records, _ = hardware.records_for(cfg)
    core = next((r for r in records if r.get("block") == Block.IK and r.get("arch") == CoreArch.PIPELINED), None)
    return {
        "config": cfg.name, "config_hash": provenance.config_hash(cfg), "width": cfg.width,
        "internal_guard_bits": cfg.internal_guard_bits, "iterations": cfg.iterations,
        "frac_length": cfg.frac_length, "frac_angle": cfg.frac_angle,
        "position_max_cm": ts["fixed"]["position_cm"]["max"], "position_rms_cm": ts["fixed"]["position_cm"]["rms"],
        "position_p99_9_cm": ts["fixed"]["position_cm"].get("p99.9"),
        "approach_max_rad": ts["fixed"]["approach_rad"]["max"],
        "joint_max_rad": max(v["max_rad"] for v in je["fixed_vs_exact"]["all"].values()),
        "joint_own_max_rad": je["floor"]["max_rad"], "joint_floor_met": je["floor"]["met"],
        "float32_position_max_cm": ts["float32"]["position_cm"]["max"],
        "fixed_over_float32_max": ts["ratio_fixed_over_float32"]["position_max"],
        "fixed_beats_float32": ts["fixed_beats_float32"], "flagged": ts["fixed_flagged"]["count"],
        "core": hardware.row_of(core) if core else None,
    }


def _plot(rows: list[dict], out_dir: Path) -> str:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2))
    x = [r["width"] + r["internal_guard_bits"] for r in rows]   # the bits the IK computes on
    for key, label, marker in (("position_max_cm", "max", "o"), ("position_rms_cm", "RMS", "s")):
        left.plot(x, [r[key] for r in rows], marker=marker, ls="-", label=f"fixed {label}")
    left.axhline(rows[0]["float32_position_max_cm"], color="grey", ls=":", label="float32 max")
    right.plot(x, [r["joint_max_rad"] for r in rows], marker="o", label="end to end, max")
    right.plot(x, [r["joint_own_max_rad"] for r in rows], marker="s", label="solver's own, |sin q3| ≥ 1e-3")
    right.axhline(1e-6, color="grey", ls=":", label="joint floor 1e-6 rad")
    for ax, unit in ((left, "position error (cm)"), (right, "joint error (rad)")):
        for r, xi in zip(rows, x):
            ax.annotate(r["config"], (xi, r["position_max_cm"] if ax is left else r["joint_max_rad"]),
                        fontsize=8, xytext=(3, 4), textcoords="offset points")
        ax.set_yscale("log")
        ax.set_xlabel("bits inside the IK: word width + internal guard bits")
        ax.set_ylabel(unit)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    left.set_title("Task-space error against bits")
    right.set_title("Joint error against bits")
    fig.tight_layout()
    fig.savefig(out_dir / "error_vs_bits.png", dpi=110)
    plt.close(fig)
    return "error_vs_bits.png"


def _table(rows: list[dict]) -> str:
    header = ("config", "width", "internal guard bits", "position max (cm)", "position RMS (cm)",
              "approach max (rad)", "joint max (rad)", "joint own max (rad)", "joint floor",
              "fixed/float32 max", "beats float32", "flagged poses", "core LUT4 sites", "DSPs",
              "Fmax (MHz)", "latency (cycles)")
    cells = []
    for r in rows:
        core = r["core"] or {}
        cells.append((r["config"], r["width"], r["internal_guard_bits"], r["position_max_cm"],
                      r["position_rms_cm"], r["approach_max_rad"], r["joint_max_rad"], r["joint_own_max_rad"],
                      "met" if r["joint_floor_met"] else "not met", r["fixed_over_float32_max"],
                      r["fixed_beats_float32"], r["flagged"], core.get("lut4_sites"), core.get("dsps"),
                      core.get("fmax_mhz"), core.get("latency_cycles")))
    return table(header, cells, caption="One row per config (same poses); hardware: pipelined IK core record")


def build_comparison(out_dir, names: list[str], vectors: int = 100_000, arm: Arm | str | None = None,
                     seed: int = 0, *, progress: bool = False, log=print) -> dict:
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    arm_ = arm if isinstance(arm, Arm) else load_arm(arm)
    cfgs = [load_config(name) for name in names]     # every config read before any is computed
    rows = []
    for cfg in cfgs:
        log(f"{cfg.name}: {vectors:,} poses")
        rows.append(config_row(figures(compute(arm_, cfg, vectors, seed, progress=progress)), cfg))
    img = _plot(rows, out_dir)
    prov = provenance.provenance()
    sections = [
        Section("configs", "Configs compared", para(
            f"The quantisation report's figures of each config on the same {vectors:,} random reachable "
            f"poses (seed {seed}, arm {arm_.name}): fixed point against float64 (position: FK of the solved "
            "joints against the target; joint own error: against float64 on the same input words). "
            "Hardware columns from docs/results/records (– where none is committed).")
            + _table(rows) + image(img, "Error against word width")),
        Section("provenance", "Provenance", table(("provenance", "value"), provenance.rows(prov))),
    ]
    meta = {"report": "comparison", "configs": [c.name for c in cfgs], "arm": arm_.name, "vectors": vectors,
            "seed": seed, "generated_utc": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
            "ik5r": prov["package_version"], "git_commit": prov["git_commit"], "provenance": prov}
    doc = jsonable({"meta": meta, "configs": rows})
    (out_dir / "report.json").write_text(json.dumps(doc, indent=2, allow_nan=False) + "\n")
    (out_dir / "index.html").write_text(render_page(f"ik5r config comparison: {', '.join(meta['configs'])}",
                                                    sections, meta))
    return doc


def summary_lines(doc: dict) -> list[str]:
    lines = [f"{'config':8}{'width':>6}{'guard':>6}{'pos max cm':>12}{'pos RMS cm':>12}{'joint max rad':>14}"
             f"{'fixed/f32':>10}{'Fmax MHz':>10}"]
    for r in doc["configs"]:
        fmax = (r["core"] or {}).get("fmax_mhz")
        lines.append(f"{r['config']:8}{r['width']:>6}{r['internal_guard_bits']:>6}{r['position_max_cm']:>12.3g}"
                     f"{r['position_rms_cm']:>12.3g}{r['joint_max_rad']:>14.3g}{r['fixed_over_float32_max']:>10.3g}"
                     f"{'–' if fmax is None else format(fmax, '.1f'):>10}")
    return lines
