"""Word-length design-space sweep: accuracy (bit-accurate model) against area and Fmax (synthesis).

Configs come from the schema of ik5r.core.fxconfig by one rule of the word width ``w``
(:func:`config_for`), which reproduces the shipped ``configs/q18.toml``, ``q24.toml`` and
``q32.toml`` exactly:

=====================  =========================  ==================================================
field                  rule                       why
=====================  =========================  ==================================================
``frac.length``        ``w - 8``                  8 integer bits (sign included): |p| < 128 cm; with
                                                  ``--arm``: ``w - armfit.integer_bits_for(arm)``
``frac.unit``          ``w - 2``                  unit-vector components in [-1, 1] (Q1.(w-2))
``frac.angle``         ``w - 3``                  angles in [-pi, pi] (Q2.(w-3)), pi < 4
``cordic.iterations``  ``w``                      one micro-rotation per bit (override: --iterations)
``cordic.guard_bits``  ``round(log2 w) - 1``      ~log2(iterations) rounding steps accumulate
``angle_guard_bits``   ``3``
``ik.rounding``        ``nearest``
``ik.internal_guard``  ``0``                      override: --guard-bits
=====================  =========================  ==================================================

Each point = (config, block, architecture); with ``synth=False`` (``--no-synth``) one point per
config and no block. Its error figures are those of the whole fixed-point IK at that config
(``ik5r.tools.report.quantisation``: ``poses`` random reachable poses, fixed point against float64). Its
area and Fmax come from :func:`ik5r.tools.synth.synthesize`. The error of a config is computed once and
shared by its blocks and architectures.

Every task runs on a Dask distributed cluster: the one at ``scheduler`` (``tcp://HOST:PORT``), else
a ``LocalCluster`` of ``jobs`` worker processes on this machine. Each task has a key derived from
its cache key, so the scheduler holds it once; a worker lost mid-task has its task re-run on
another worker by the scheduler. Every finished task is cached in ``DIR/cache/`` by this process
(keyed by the config, the options and a hash of the sources it depends on), so an interrupted
sweep resumes and a finished one re-runs in seconds; synthesis runs are also cached under the
synth cache (``build/synth`` by default, on the worker's machine).
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import os
import time
from contextlib import contextmanager
from dataclasses import asdict, dataclass
from pathlib import Path

from ik5r.core.fxconfig import FixedConfig, parse_config
from ik5r.core.modes import Arch, Target
from ik5r.hdl.generate import resolve_arch

from .sweep_outputs import CSV_FIELDS, pareto_flags, write_outputs  # noqa: F401 (the API of old)
from .sweep_record import DEFAULT_POSES, DEFAULT_WIDTHS, SweepOptions, SweepRecord  # noqa: F401
from .synth import SynthOptions, synthesize, tool_versions

#: LFE5U-25F capacities (nextpnr's device utilisation): would a point fit the small ECP5?
ECP5_25K = {"luts": 24288, "ffs": 24288, "dsps": 28, "brams": 56}
ANGLE_GUARD_BITS = 3
SYNTH_FIELDS = ("luts", "lut4", "carry", "ffs", "dsps", "brams", "lutram", "fits_device", "fmax_mhz",
                "latency_cycles", "cycles_per_result", "results_per_second", "latency_ns", "target",
                "device", "package", "speed_grade", "synth_seconds", "critical_path", "cache_dir")


# --- configs -------------------------------------------------------------------------------------

def guard_bits_for(width: int) -> int:
    return max(0, min(8, round(math.log2(width)) - 1))


def config_for(width: int, iterations: int | None = None, internal_guard_bits: int | None = None,
               arm=None) -> FixedConfig:
    """The config of word width ``width`` by the rule of the module docstring; ``arm``: its
    length format holds that arm (:func:`ik5r.core.armfit.integer_bits_for`; 8 bits for the
    arm of record, as the shipped configs)."""
    from ik5r.core.armfit import integer_bits_for

    int_bits = 8 if arm is None else integer_bits_for(arm)
    iters = width if iterations is None else iterations
    name = f"w{width}" + ("" if iterations is None else f"i{iters}")
    name += "" if internal_guard_bits is None else f"g{internal_guard_bits}"
    doc = {
        "name": name, "width": width,
        "frac": {"length": width - int_bits, "unit": width - 2, "angle": width - 3},
        "cordic": {"iterations": iters, "guard_bits": guard_bits_for(width),
                   "angle_guard_bits": ANGLE_GUARD_BITS},
        "ik": {"rounding": "nearest", "singular_sin_q3": 1e-3,
               "internal_guard_bits": internal_guard_bits or 0,
               # The format's reach tolerance 2**(10 - width), to two digits as the configs state it.
               "reach_tolerance": float(f"{2.0 ** (10 - width):.2g}")},
    }
    return parse_config(doc, f"<sweep {name}>")


def sweep_configs(widths, iterations=None, internal_guard_bits=None, arm=None) -> list[FixedConfig]:
    """Every config of the sweep: widths x iteration counts x internal guard bits."""
    return [config_for(w, it, g, arm) for w in widths for it in (iterations or [None])
            for g in (internal_guard_bits or [None])]


def _config_key(cfg: FixedConfig) -> str:
    """The numbers of a config (not its name or source)."""
    d = asdict(cfg)
    d.pop("name"), d.pop("source")
    return json.dumps(d, sort_keys=True)


# --- cache keys ----------------------------------------------------------------------------------

def _package_dir(module: str) -> Path:
    import importlib
    return Path(importlib.import_module(module).__file__).parent


def error_sources_hash() -> str:
    """Hash of every source the error figures come from: the import closure of the quantisation
    report (:mod:`ik5r.tools.sources`) and the arm data."""
    from .sources import closure_hash
    return closure_hash(["ik5r.tools.report.quantisation", "ik5r.tools.sweep_error"],
                        sorted((_package_dir("ik5r") / "data").glob("*.toml")))


def hdl_sources_hash() -> str:
    """Hash of every source the Verilog and its synthesis come from: the import closure of
    ``ik5r.hdl.generate`` and ``ik5r.tools.synth`` (the firmware model, status bits, fixed point, config,
    arm, ... as the modules import them), the arm data and the compact core's kept block orders."""
    from ik5r.hdl.sequenced.hints import schedule_files

    from .sources import closure_hash
    return closure_hash(["ik5r.hdl.generate", "ik5r.tools.synth"],
                        sorted((_package_dir("ik5r") / "data").glob("*.toml")) + schedule_files())


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

def error_task(cfg: FixedConfig, poses: int, seed: int, arm=None) -> dict:
    """Error figures of the fixed-point IK at ``cfg`` against float64 (see ik5r.tools.sweep_error)."""
    from .sweep_error import error_figures

    start, cpu = time.perf_counter(), time.process_time()
    doc = error_figures(cfg, poses, seed, arm)
    doc["error_seconds"] = round(time.perf_counter() - start, 2)
    doc["error_cpu_seconds"] = round(time.process_time() - cpu, 2)
    return doc


def synth_task(block: str, arch: str, cfg: FixedConfig, opts: SynthOptions, cache_dir: str,
               timeout: float | None, arm=None) -> dict:
    from .design import Design

    start = time.perf_counter()
    try:
        design = Design.resolve(block, arch, config=cfg, arm=arm)
        result = synthesize(design, opts, cache_dir=cache_dir, timeout=timeout)
    except Exception as exc:  # reported per point; the sweep goes on
        return {"error": f"{type(exc).__name__}: {exc}"[:2000]}
    result["synth_seconds"] = round(time.perf_counter() - start, 2)
    return result


# --- planning: what is cached, what runs ---------------------------------------------------------

@dataclass
class Task:
    kind: str        # "error" or "synth"
    ident: object    # config name, or (config name, block, arch)
    path: Path       # cache file
    call: tuple      # (function, *args)
    width: int

    @property
    def key(self) -> str:
        """The Dask key: one per cached result, so the scheduler never holds a task twice."""
        return f"ik5r-{self.kind}-{self.path.stem}"


def _plan(configs, blocks, archs, poses, seed, opts, synth_cache, timeout, cache: Path, arm=None):
    """(error figures cached, synthesis figures cached, tasks to run), longest tasks first; the
    arm (None: the arm of record, whose cache names stay as they were) is in every key."""
    arm_tag = "" if arm is None else f"_arm-{arm.name}-{arm.dh_sha256()}"
    opts_key = {k: v for k, v in asdict(opts).items() if k != "threads"}
    # One nextpnr thread per task: the workers already fill the cores.
    worker_opts = SynthOptions(**{**asdict(opts), "threads": 1})
    err_hash = error_sources_hash()
    hdl_hash, tools = (hdl_sources_hash(), tool_versions(opts.target)) if blocks else (None, None)
    errors, synths, pending = {}, {}, []
    for cfg in configs:
        path = cache / f"error_{cfg.name}{arm_tag}_{_key(_config_key(cfg), poses, seed, err_hash)}.json"
        doc = _read_cache(path)
        if doc is not None:
            errors[cfg.name] = dict(doc, from_cache=True)
        else:
            pending.append(Task("error", cfg.name, path, (error_task, cfg, poses, seed, arm), cfg.width))
        for block in blocks:
            for arch in dict.fromkeys(resolve_arch(block, a) for a in archs):
                key = _key(_config_key(cfg), block, arch, opts_key, hdl_hash, tools)
                path = cache / f"synth_{block}_{arch}_{cfg.name}{arm_tag}_{key}.json"
                doc = _read_cache(path)
                if doc is not None and "error" not in doc:
                    synths[(cfg.name, block, arch)] = dict(doc, from_cache=True)
                else:
                    call = (synth_task, block, arch, cfg, worker_opts, str(synth_cache), timeout, arm)
                    pending.append(Task("synth", (cfg.name, block, arch), path, call, cfg.width))
    # Longest first (wide pipelined synthesis), so the workers end together.
    pending.sort(key=lambda t: (t.kind != "synth", -t.width,
                                t.kind == "synth" and t.ident[2] != Arch.PIPELINED))
    return errors, synths, pending, opts_key, tools


# --- the Dask cluster ----------------------------------------------------------------------------

@contextmanager
def dask_client(scheduler: str | None = None, jobs: int | None = None):
    """A Dask client: of the cluster at ``scheduler``, else of a LocalCluster of ``jobs`` processes."""
    from dask.distributed import Client, LocalCluster

    from ik5r.core.errors import InputError

    if scheduler:
        try:
            client = Client(scheduler, timeout="20s")
        except (OSError, TimeoutError) as exc:
            raise InputError("--scheduler", f"cannot reach the Dask scheduler at {scheduler}: {exc}") from None
        with client:
            yield client
        return
    with LocalCluster(n_workers=jobs or os.cpu_count() or 1, threads_per_worker=1, processes=True,
                      dashboard_address=":0", silence_logs=logging.ERROR) as cluster, Client(cluster) as client:
        yield client


def _describe(task: Task, doc: dict) -> str:
    if "error" in doc:
        return f"  {task.kind} {task.ident}: FAILED {str(doc['error']).splitlines()[0]}"
    if task.kind == "error":
        return (f"  error {task.ident}: position max {doc['position_err_max_cm']:.3g} cm, "
                f"RMS {doc['position_err_rms_cm']:.3g} cm ({doc['error_seconds']:.1f} s)")
    name, block, arch = task.ident
    return (f"  synth {block} {arch} {name}: {doc['luts']} LUT, {doc['ffs']} FF, {doc['dsps']} DSP, "
            f"Fmax {doc['fmax_mhz']:.1f} MHz ({doc['synth_seconds']:.0f} s"
            f"{', cached' if doc.get('cached') else ''})")


def run_tasks(client, pending: list[Task], *, progress: bool = False, note=None, on_done=None) -> dict:
    """Submit every task to ``client``; cache each result as it arrives; {task key: result}.

    A task whose worker dies is re-run by the scheduler (up to distributed.scheduler.allowed-failures
    times); one that raises, or that kills its workers that often, comes back as {"error": ...}.
    """
    from dask.distributed import as_completed
    from tqdm import tqdm

    futures = {client.submit(task.call[0], *task.call[1:], key=task.key, pure=False): task
               for task in pending}
    results = {}
    with tqdm(total=len(futures), desc="sweep", unit="task", disable=not progress,
              dynamic_ncols=True) as bar:
        for fut in as_completed(futures):
            task = futures[fut]
            try:
                doc = fut.result()
            except Exception as exc:  # the task raised, or its workers kept dying
                doc = {"error": f"{type(exc).__name__}: {exc}"[:2000]}
            if task.key in results:
                raise RuntimeError(f"task {task.key} came back twice")
            results[task.key] = doc
            if "error" not in doc:
                _write_cache(task.path, doc)
            bar.update(1)
            if note and progress:
                bar.write(_describe(task, doc))
            elif note:
                note(_describe(task, doc))
            if on_done:
                on_done(task, doc)
    return results


# --- the sweep -----------------------------------------------------------------------------------

def _point(cfg: FixedConfig, block, arch, err: dict, syn: dict) -> dict:
    p = {"name": cfg.name, "block": block, "arch": arch, "width": cfg.width,
         "frac_length": cfg.frac_length, "frac_unit": cfg.frac_unit, "frac_angle": cfg.frac_angle,
         "iterations": cfg.iterations, "guard_bits": cfg.guard_bits,
         "angle_guard_bits": cfg.angle_guard_bits, "internal_guard_bits": cfg.internal_guard_bits,
         "config_toml": cfg.to_toml()}
    p.update({k: v for k, v in err.items() if k not in ("from_cache",)})
    p.update({k: syn[k] for k in SYNTH_FIELDS if k in syn})
    if "error" in syn:
        p["synth_error"] = syn["error"]
    if syn.get("target") == Target.ECP5 and syn.get("luts") is not None:
        # Estimate from the counts (the 85k P&R packing): LUT sites, FFs, DSPs, EBRs.
        p["fits_ecp5_25k_est"] = all(syn[k] <= cap for k, cap in ECP5_25K.items())
    p["error_from_cache"] = bool(err.get("from_cache"))
    p["synth_from_cache"] = bool(syn.get("from_cache"))
    return p


def run_sweep(options: SweepOptions = SweepOptions(), *, arm=None, out_dir="build/sweep",
              jobs: int | None = None, scheduler: str | None = None, client=None, progress: bool = True,
              log=print, note=None, on_done=None) -> SweepRecord:
    """Run (or resume) the sweep of ``options`` for ``arm`` (None: the arm of record) on Dask;
    writes DIR/sweep.csv, sweep.json (:meth:`SweepRecord.write`), the plots and index.html.

    ``client``: an open Dask client to use (else one of ``scheduler``, else a LocalCluster of
    ``jobs`` processes). ``note``: called with a line per finished task; ``on_done``: with each
    finished task and its result.
    """
    start = time.perf_counter()
    o = options
    out_dir = Path(out_dir)
    blocks = list(o.blocks) if o.synth else []
    archs = list(dict.fromkeys(o.archs)) if o.synth else []
    opts = o.synth_options.resolved()
    configs = sweep_configs(o.widths, o.iterations, o.guard_bits, arm)
    errors, synths, pending, opts_key, tools = _plan(configs, blocks, archs, o.poses, o.seed, opts,
                                                     o.synth_cache, o.timeout, out_dir / "cache", arm)
    cached_count = len(errors) + len(synths)
    where = f"the Dask cluster at {scheduler}" if scheduler else \
        "the given Dask client" if client else f"a LocalCluster of {jobs or os.cpu_count()} process(es)"
    log(f"sweep: {len(configs)} config(s) x {len(blocks) or 'no'} block(s) x {len(archs) or 'no'} "
        f"arch(s); {cached_count} task(s) cached, {len(pending)} to run on {where if pending else 'nothing'}")
    results = {}
    if pending and client is not None:
        results = run_tasks(client, pending, progress=progress, note=note, on_done=on_done)
    elif pending:
        with dask_client(scheduler, jobs) as own:
            results = run_tasks(own, pending, progress=progress, note=note, on_done=on_done)
    failures = []
    for task in pending:
        doc = results[task.key]
        (errors if task.kind == "error" else synths)[task.ident] = doc
        if "error" in doc:
            failures.append((task.ident if task.kind == "synth" else (task.ident,), doc["error"]))
    points = _points(configs, blocks, archs, errors, synths, o.synth)
    meta = {
        "rule": "frac.length = w-8, frac.unit = w-2, frac.angle = w-3, iterations = w (or "
                "--iterations), guard_bits = round(log2 w)-1, angle_guard_bits = 3, nearest, "
                "ik.internal_guard_bits = --guard-bits (0)",
        "arm": "hu-5r" if arm is None else arm.name, "arm_sha256": None if arm is None else arm.dh_sha256(),
        "widths": list(o.widths), "iterations": list(o.iterations) if o.iterations else "auto",
        "internal_guard_bits": list(o.guard_bits) if o.guard_bits else [0],
        "blocks": blocks, "archs": archs, "synth": o.synth, "poses": o.poses, "seed": o.seed,
        "synth_options": opts_key if o.synth else None, "tools": tools,
        "cluster": scheduler or ("client" if client else f"LocalCluster({jobs or os.cpu_count()})"),
        "tasks_run": len(pending), "tasks_cached": cached_count,
        "failures": [{"point": list(i), "error": e} for i, e in failures],
    }
    meta["elapsed_s"] = round(time.perf_counter() - start, 2)
    record = SweepRecord(meta, tuple(points))
    write_outputs(record, out_dir, freq_floor=150.0 if Arch.PIPELINED in archs else None)
    log(f"sweep: {len(points)} point(s) in {meta['elapsed_s']:.1f} s -> {out_dir}/sweep.csv, "
        f"sweep.json, index.html and plots")
    return record


def _points(configs, blocks, archs, errors: dict, synths: dict, synth: bool) -> list[dict]:
    """The points in sweep order: per config, its blocks x archs (or one point without synthesis)."""
    points = []
    for cfg in configs:
        err = errors.get(cfg.name, {})
        if not synth:
            points.append(_point(cfg, "", "", err, {}))
        for block in blocks:
            for arch in dict.fromkeys(resolve_arch(block, a) for a in archs):
                points.append(_point(cfg, block, arch, err, synths.get((cfg.name, block, arch), {})))
    return points
