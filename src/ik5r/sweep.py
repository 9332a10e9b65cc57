"""Word-length design-space sweep: accuracy (bit-accurate model) against area and Fmax (synthesis).

Configs come from the schema of :mod:`ik5r.fxconfig` by one rule of the word width ``w``
(:func:`config_for`), which reproduces the shipped ``configs/q18.toml``, ``q24.toml`` and
``q32.toml`` exactly:

=====================  =========================  ==================================================
field                  rule                       why
=====================  =========================  ==================================================
``frac.length``        ``w - 8``                  8 integer bits (sign included): |p| < 128 cm
``frac.unit``          ``w - 2``                  unit-vector components in [-1, 1] (Q1.(w-2))
``frac.angle``         ``w - 3``                  angles in [-pi, pi] (Q2.(w-3)), pi < 4
``cordic.iterations``  ``w``                      one micro-rotation per bit (override: --iterations)
``cordic.guard_bits``  ``round(log2 w) - 1``      ~log2(iterations) rounding steps accumulate
``angle_guard_bits``   ``3``
``ik.rounding``        ``nearest``
=====================  =========================  ==================================================

Each point = (config, block, architecture). Its error figures are those of the whole fixed-point
IK at that config (``ik5r.report.quantisation``: ``poses`` random reachable poses, fixed point
against float64): max / RMS joint error and max / RMS task-space position error. Its area and
Fmax come from :func:`ik5r.synth.synthesize` on the chosen block (the IK core once it exists).
The error of a config is computed once and shared by its blocks and architectures.

Every finished task is cached in ``DIR/cache/`` (keyed by the config, the options and a hash of
the sources it depends on), so an interrupted sweep resumes and a finished one re-runs in seconds;
synthesis runs are also cached under the synth cache (``build/synth`` by default).
"""

from __future__ import annotations

import csv
import hashlib
import json
import math
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict
from pathlib import Path

from .fxconfig import FixedConfig, parse_config
from .hdl.generate import resolve_arch

from .synth import DEFAULT_CACHE, SynthOptions, synthesize, tool_versions

DEFAULT_WIDTHS = (16, 18, 20, 24, 28, 32)
#: LFE5U-25F capacities (nextpnr's device utilisation): would a point fit the small ECP5?
ECP5_25K = {"luts": 24288, "ffs": 24288, "dsps": 28, "brams": 56}
DEFAULT_POSES = 100_000
ANGLE_GUARD_BITS = 3

CSV_FIELDS = (
    "name", "block", "arch", "width", "frac_length", "frac_unit", "frac_angle", "iterations",
    "guard_bits", "angle_guard_bits", "poses", "position_err_max_cm", "position_err_rms_cm",
    "joint_err_max_rad", "joint_err_rms_rad", "joint_err_max_rad_conditioned",
    "approach_err_max_rad", "fixed_flagged", "luts", "lut4", "carry", "ffs", "dsps", "brams",
    "lutram", "fits_device", "fits_ecp5_25k_est", "fmax_mhz", "latency_cycles", "cycles_per_result", "results_per_second", "device",
    "speed_grade", "pareto", "synth_seconds", "error_seconds",
)


# --- configs -------------------------------------------------------------------------------------

def guard_bits_for(width: int) -> int:
    return max(0, min(8, round(math.log2(width)) - 1))


def config_for(width: int, iterations: int | None = None) -> FixedConfig:
    """The config of word width ``width`` by the rule of the module docstring."""
    iters = width if iterations is None else iterations
    name = f"w{width}" if iterations is None else f"w{width}i{iters}"
    doc = {
        "name": name, "width": width,
        "frac": {"length": width - 8, "unit": width - 2, "angle": width - 3},
        "cordic": {"iterations": iters, "guard_bits": guard_bits_for(width),
                   "angle_guard_bits": ANGLE_GUARD_BITS},
        "ik": {"rounding": "nearest", "singular_sin_q3": 1e-3},
    }
    return parse_config(doc, f"<sweep {name}>")


def _config_key(cfg: FixedConfig) -> str:
    """The numbers of a config (not its name or source)."""
    d = asdict(cfg)
    d.pop("name"), d.pop("source")
    return json.dumps(d, sort_keys=True)


# --- cache keys ----------------------------------------------------------------------------------

def _source_hash(paths) -> str:
    h = hashlib.sha256()
    for path in sorted(paths):
        h.update(path.name.encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def _package_dir(module: str) -> Path:
    import importlib
    return Path(importlib.import_module(module).__file__).parent


def error_sources_hash() -> str:
    """Hash of every source the error figures come from: the import closure of the quantisation
    report (:mod:`ik5r.sources`) and the arm data."""
    from .sources import closure_hash
    return closure_hash(["ik5r.report.quantisation"],
                        sorted((_package_dir("ik5r") / "data").glob("*.toml")))


def hdl_sources_hash() -> str:
    """Hash of every source the Verilog and its synthesis come from: the import closure of
    ``ik5r.hdl.generate`` and ``ik5r.synth`` (the firmware model, status bits, fixed point, config,
    arm, ... as the modules import them) and the arm data."""
    from .sources import closure_hash
    return closure_hash(["ik5r.hdl.generate", "ik5r.synth"],
                        sorted((_package_dir("ik5r") / "data").glob("*.toml")))


def _key(*parts) -> str:
    return hashlib.sha256(json.dumps(parts, sort_keys=True, default=str).encode()).hexdigest()[:20]


def _read_cache(path: Path):
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def _write_cache(path: Path, doc) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(f".{os.getpid()}.tmp")
    tmp.write_text(json.dumps(doc, indent=2) + "\n")
    os.replace(tmp, path)


# --- the two kinds of task (run in worker processes) ---------------------------------------------

def error_task(cfg: FixedConfig, poses: int, seed: int) -> dict:
    """Error figures of the fixed-point IK at ``cfg`` against float64 (quantisation report)."""
    from .arm import load_arm
    from .report import quantisation as qz

    start = time.perf_counter()
    samples = qz.compute(load_arm(), cfg, poses, seed, progress=False)
    task = qz.task_figures(samples)
    joints = qz.joint_figures(samples)
    per_joint = joints["fixed_vs_exact"]["all"]
    conditioned = joints["fixed_vs_exact_off_axis"]["sin_q3_ge_1e-2"]

    def jmax(per):
        values = [v["max_rad"] for v in per.values() if v["max_rad"] is not None]
        return max(values) if values else None

    rms = [v["rms_rad"] for v in per_joint.values() if v["rms_rad"] is not None]
    fixed = task["fixed"]
    return {
        "poses": poses, "seed": seed,
        "position_err_max_cm": fixed["position_cm"]["max"],
        "position_err_rms_cm": fixed["position_cm"]["rms"],
        "position_err_p99_cm": fixed["position_cm"].get("p99"),
        "approach_err_max_rad": fixed["approach_rad"]["max"],
        "approach_err_rms_rad": fixed["approach_rad"]["rms"],
        "joint_err_max_rad": jmax(per_joint),
        "joint_err_rms_rad": math.sqrt(sum(r * r for r in rms) / len(rms)) if rms else None,
        "joint_err_max_rad_conditioned": jmax(conditioned),
        "joint_err_per_joint": {j: {"max_rad": v["max_rad"], "rms_rad": v["rms_rad"]}
                                for j, v in per_joint.items()},
        "fixed_flagged": task["fixed_flagged"]["count"],
        "float32_position_err_max_cm": task["float32"]["position_cm"]["max"],
        "float32_position_err_rms_cm": task["float32"]["position_cm"]["rms"],
        "error_seconds": round(time.perf_counter() - start, 2),
    }


def synth_task(block: str, arch: str, cfg: FixedConfig, opts: SynthOptions, cache_dir: str,
               timeout: float | None) -> dict:
    start = time.perf_counter()
    try:
        result = synthesize(block, arch, cfg, opts, cache_dir=cache_dir, timeout=timeout)
    except Exception as exc:  # reported per point; the sweep goes on
        return {"error": f"{type(exc).__name__}: {exc}"[:2000]}
    result["synth_seconds"] = round(time.perf_counter() - start, 2)
    return result


# --- Pareto front and outputs --------------------------------------------------------------------

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

    names = []
    markers = {"pipelined": "o", "iterative": "s"}
    groups = sorted({(p["block"], p["arch"]) for p in points})
    colours = {g: f"C{i}" for i, g in enumerate(groups)}

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
    ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    fig.savefig(out_dir / "error_vs_luts.png", dpi=120)
    plt.close(fig)
    names.append("error_vs_luts.png")

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
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out_dir / "fmax_vs_width.png", dpi=120)
    plt.close(fig)
    names.append("fmax_vs_width.png")
    return names


def _html(points: list[dict], meta: dict, out_dir: Path) -> None:
    from .report.html import Section, image, para, render_page, table

    header = ["point", "block", "arch", "width", "iter", "pos max (cm)", "pos RMS (cm)",
              "joint max (rad)", "joint RMS (rad)", "LUTs", "FFs", "DSP", "Fmax (MHz)",
              "results/s", "Pareto"]
    rows = [[p["name"], p["block"], p["arch"], p["width"], p["iterations"],
             p.get("position_err_max_cm"), p.get("position_err_rms_cm"),
             p.get("joint_err_max_rad"), p.get("joint_err_rms_rad"), p.get("luts"), p.get("ffs"),
             p.get("dsps"), p.get("fmax_mhz"), p.get("results_per_second"),
             "yes" if p.get("pareto") else ""] for p in points]
    sections = [
        Section("points", "Sweep points", table(header, rows)),
        Section("plots", "Plots", image("error_vs_luts.png", "position error against LUTs")
                + image("fmax_vs_width.png", "Fmax against word width")),
        Section("rule", "Config rule", para(
            "frac.length = w − 8, frac.unit = w − 2, frac.angle = w − 3, iterations = w, "
            "guard_bits = round(log2 w) − 1, angle_guard_bits = 3, rounding nearest "
            "(reproduces configs/q18, q24, q32).")),
    ]
    (out_dir / "index.html").write_text(render_page("ik5r word-length sweep", sections,
                                                    {k: v for k, v in meta.items()
                                                     if isinstance(v, (str, int, float))}))


def write_outputs(points: list[dict], meta: dict, out_dir: Path, freq_floor: float | None = 150.0):
    from .report.html import jsonable

    out_dir.mkdir(parents=True, exist_ok=True)
    for p, flag in zip(points, pareto_flags(points)):
        p["pareto"] = flag
    with open(out_dir / "sweep.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=CSV_FIELDS, extrasaction="ignore")
        writer.writeheader()
        for p in points:
            writer.writerow({k: ("" if p.get(k) is None else p.get(k)) for k in CSV_FIELDS})
    doc = jsonable({"meta": meta, "points": points})
    (out_dir / "sweep.json").write_text(json.dumps(doc, indent=2, allow_nan=False) + "\n")
    images = _plots(points, out_dir, freq_floor)
    _html(points, meta, out_dir)
    return images


# --- the sweep -----------------------------------------------------------------------------------

def run_sweep(widths=DEFAULT_WIDTHS, iterations=None, blocks=("atan2",), archs=("pipelined",),
              out_dir="build/sweep", jobs: int | None = None, poses: int = DEFAULT_POSES,
              seed: int = 0, opts: SynthOptions | None = None, synth_cache=DEFAULT_CACHE,
              timeout: float | None = None, progress: bool = True, log=print) -> dict:
    """Run (or resume) a sweep; writes DIR/sweep.csv, sweep.json, the plots and index.html."""
    from tqdm import tqdm

    start = time.perf_counter()
    out_dir = Path(out_dir)
    cache = out_dir / "cache"
    jobs = jobs or os.cpu_count() or 1
    opts = (opts or SynthOptions()).resolved()
    # One nextpnr thread per job: the jobs already fill the cores.
    opts_key = {k: v for k, v in asdict(opts).items() if k != "threads"}
    # "iterative" and "compact" name the same choice (the IK core calls it compact).
    archs = list(dict.fromkeys(archs))
    configs = []
    for w in widths:
        for it in (iterations or [None]):
            configs.append(config_for(w, it))
    err_hash, hdl_hash = error_sources_hash(), hdl_sources_hash()
    tools = tool_versions(opts.target)

    errors, synths = {}, {}
    pending = []  # (kind, id, cache path, callable args)
    for cfg in configs:
        path = cache / f"error_{cfg.name}_{_key(_config_key(cfg), poses, seed, err_hash)}.json"
        doc = _read_cache(path)
        if doc is not None:
            errors[cfg.name] = dict(doc, from_cache=True)
        else:
            pending.append(("error", cfg.name, path, (error_task, cfg, poses, seed)))
        for block in blocks:
            for arch in dict.fromkeys(resolve_arch(block, a) for a in archs):
                key = _key(_config_key(cfg), block, arch, opts_key, hdl_hash, tools)
                path = cache / f"synth_{block}_{arch}_{cfg.name}_{key}.json"
                doc = _read_cache(path)
                if doc is not None and "error" not in doc:
                    synths[(cfg.name, block, arch)] = dict(doc, from_cache=True)
                else:
                    pending.append(("synth", (cfg.name, block, arch), path,
                                    (synth_task, block, arch, cfg, opts, str(synth_cache), timeout)))
    # Longest first (wide pipelined synthesis), so the pool ends together.
    widths_of = {cfg.name: cfg.width for cfg in configs}
    pending.sort(key=lambda t: (t[0] != "synth", -widths_of[t[1][0] if t[0] == "synth" else t[1]],
                                t[0] == "synth" and t[1][2] != "pipelined"))
    cached_count = len(errors) + len(synths)
    log(f"sweep: {len(configs)} configs x {len(blocks)} block(s) x {len(archs)} arch(s); "
        f"{cached_count} task(s) cached, {len(pending)} to run on {min(jobs, max(1, len(pending)))} "
        f"process(es)")
    failures = []
    if pending:
        worker_opts = SynthOptions(**{**asdict(opts), "threads": 1})
        with ProcessPoolExecutor(max_workers=min(jobs, len(pending))) as pool:
            futures = {}
            for kind, ident, path, (fn, *args) in pending:
                if kind == "synth":
                    args[3] = worker_opts
                futures[pool.submit(fn, *args)] = (kind, ident, path)
            bar = tqdm(total=len(futures), desc="sweep", unit="task", disable=not progress,
                       dynamic_ncols=True)
            for fut in as_completed(futures):
                kind, ident, path = futures[fut]
                try:
                    doc = fut.result()
                except Exception as exc:  # a worker died
                    doc = {"error": f"{type(exc).__name__}: {exc}"}
                bar.update(1)
                if kind == "error":
                    errors[ident] = doc
                    _write_cache(path, doc)
                    bar.write(f"  error {ident}: position max {doc['position_err_max_cm']:.3g} cm, "
                              f"RMS {doc['position_err_rms_cm']:.3g} cm ({doc['error_seconds']:.0f} s)")
                elif "error" in doc:
                    failures.append((ident, doc["error"]))
                    synths[ident] = doc
                    bar.write(f"  synth {' '.join(ident)}: FAILED {doc['error'].splitlines()[0]}", file=sys.stderr)
                else:
                    synths[ident] = doc
                    _write_cache(path, doc)
                    bar.write(f"  synth {ident[1]} {ident[2]} {ident[0]}: {doc['luts']} LUT, "
                              f"{doc['ffs']} FF, {doc['dsps']} DSP, Fmax {doc['fmax_mhz']:.1f} MHz "
                              f"({doc['synth_seconds']:.0f} s{', cached' if doc.get('cached') else ''})")
            bar.close()

    points = []
    for cfg in configs:
        err = errors.get(cfg.name, {})
        for block in blocks:
            for arch in dict.fromkeys(resolve_arch(block, a) for a in archs):
                syn = synths.get((cfg.name, block, arch), {})
                p = {"name": cfg.name, "block": block, "arch": arch, "width": cfg.width,
                     "frac_length": cfg.frac_length, "frac_unit": cfg.frac_unit,
                     "frac_angle": cfg.frac_angle, "iterations": cfg.iterations,
                     "guard_bits": cfg.guard_bits, "angle_guard_bits": cfg.angle_guard_bits,
                     "config_toml": cfg.to_toml()}
                p.update({k: v for k, v in err.items() if k not in ("from_cache",)})
                for k in ("luts", "lut4", "carry", "ffs", "dsps", "brams", "lutram", "fits_device", "fmax_mhz",
                          "latency_cycles", "cycles_per_result", "results_per_second",
                          "latency_ns", "target", "device", "package", "speed_grade",
                          "synth_seconds", "critical_path", "cache_dir", "error"):
                    if k in syn:
                        p["synth_error" if k == "error" else k] = syn[k]
                if syn.get("target") == "ecp5" and syn.get("luts") is not None:
                    # Estimate from the counts (the 85k P&R packing): LUT sites, FFs, DSPs, EBRs.
                    p["fits_ecp5_25k_est"] = all(syn[k] <= cap for k, cap in ECP5_25K.items())
                p["error_from_cache"] = bool(err.get("from_cache"))
                p["synth_from_cache"] = bool(syn.get("from_cache"))
                points.append(p)
    meta = {
        "rule": "frac.length = w-8, frac.unit = w-2, frac.angle = w-3, iterations = w (or "
                "--iterations), guard_bits = round(log2 w)-1, angle_guard_bits = 3, nearest",
        "widths": list(widths), "iterations": list(iterations) if iterations else "auto",
        "blocks": list(blocks), "archs": list(archs), "poses": poses, "seed": seed,
        "synth_options": opts_key, "tools": tools, "jobs": jobs,
        "tasks_run": len(pending), "tasks_cached": cached_count,
        "failures": [{"point": list(i), "error": e} for i, e in failures],
        "elapsed_s": None,
    }
    meta["elapsed_s"] = round(time.perf_counter() - start, 2)
    write_outputs(points, meta, out_dir, freq_floor=150.0 if "pipelined" in archs else None)
    meta["elapsed_s"] = round(time.perf_counter() - start, 2)
    log(f"sweep: {len(points)} point(s) in {meta['elapsed_s']:.1f} s -> {out_dir}/sweep.csv, "
        f"sweep.json, error_vs_luts.png, fmax_vs_width.png")
    return {"meta": meta, "points": points}
