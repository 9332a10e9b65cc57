"""Regenerate the README's results section from measurement records kept in the repository.

    python -m ik5r.tools.results [--build build] [--sweep build/sweep] [--readme README.md] [--no-collect]

Two steps:

1. **collect** (skipped with ``--no-collect``): the measurements of this machine's ``build/`` are
   copied into ``docs/results/records/``: each ``build/synth/*/result.json`` (``ik5r synth``, a
   shipped config, nextpnr seed 1, whose Verilog is what this checkout generates) as
   ``synth/<module>_<config>_<target>-<device>.json`` with the SHA-256 of that Verilog (of its
   body: the text after the header comment, whose commit line changes with every commit; see
   ``ik5r.hdl.provenance``), the sweep's
   ``sweep.json`` and plots (``ik5r sweep``), and ``bench.json`` / ``bench.md`` (``make bench``).
   A record is replaced only by a newer measurement of the same design point.
2. **render**: the text between the ``<!-- results:begin -->`` and ``<!-- results:end -->``
   markers of the README is rewritten from the records alone. A synthesis record whose Verilog
   hash is not that of the Verilog this checkout generates is left out (and named on stdout).

So the figures in the README are never typed, survive a fresh clone (``build/`` is not kept), and
each one can be traced to the JSON record it came from.
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

from ik5r.core.arm import SEED_ARM
from ik5r.core.modes import Dsp

from .results_arms import arms_table
from .results_board import BoardOfCheckout, board_builds, board_part
from .routes import routes_part

BEGIN, END = "<!-- results:begin -->", "<!-- results:end -->"
REGMAP_BEGIN, REGMAP_END = "<!-- regmap:begin -->", "<!-- regmap:end -->"
SHIPPED = ("q32w", "q32", "q24", "q18")
PLOTS = ("error_vs_luts.png", "fmax_vs_width.png")
#: Keys of a synth result that describe this machine's cache, not the measurement.
LOCAL_KEYS = ("cache_dir", "cached", "key")


def _arch_label(r: dict) -> str:
    """A synthesis record's architecture and the options that make it a design point of its own."""
    arch = r["arch"] + (f" (word-serial, {r['serial']}-bit beats)" if r.get("serial") else "")
    arch += ", 16 x 31-bit product step" if r.get("wide_product") else ""
    arch += f", {r['poses']} poses a program" if r.get("poses", 1) != 1 else ""
    per_stage = r.get("rotations_per_stage", 1)
    arch += f", {per_stage} micro-rotations per stage" if per_stage != 1 else ""
    regs = r.get("dsp_output_regs", 0)
    return arch + (f", {regs} fabric register{'s' * (regs > 1)} after each DSP" if regs else "")


def _num(value, fmt="{:,.0f}") -> str:
    return "–" if value is None else fmt.format(value)


class VerilogOfCheckout:
    """The Verilog this checkout generates for the design point of a synth result (memoised)."""

    def __init__(self):
        self._texts = {}

    def text(self, r: dict) -> str:
        """The record's design point (a record without ``arm`` is of the arm of record) as this
        checkout builds it; a record of an arm not shipped here has no Verilog (empty text)."""
        from ik5r.core.errors import InputError

        from .design import Design

        dsp = r.get("dsp", Dsp.GENERIC)
        serial = r.get("serial")
        arm = r.get("arm")
        if arm is not None:
            from ik5r.core.arm import is_seed_arm, load_arm
            # The arm of record by any name is the default arm (the same Verilog, and the same
            # firmware in a SoC: compared); its records are of the default design point.
            arm = None if is_seed_arm(load_arm(arm)) else arm
        per_stage = r.get("rotations_per_stage", 1)
        # The compact core's wide product step (records made before the key: in the module name).
        wide = bool(r.get("wide_product")) or "_wide_product1_" in r.get("module", "")
        cap, regs, poses = r.get("max_dsp"), r.get("dsp_output_regs", 0), r.get("poses", 1)
        key = (r["block"], r["arch"], dsp, r["config"], r.get("tag_width", 0), serial, arm, per_stage, wide,
               cap, regs, poses)
        if key in self._texts:
            return self._texts[key]
        try:
            design = Design.resolve(r["block"], r["arch"], config=r["config"], arm=arm,
                                    tag_width=r.get("tag_width", 0), dsp=dsp, serial=serial,
                                    rotations_per_stage=per_stage, wide_product=wide, max_dsp=cap,
                                    dsp_output_regs=regs, poses=poses)
        except InputError:
            self._texts[key] = ""
            return ""
        if r["block"] == "cpu":
            from .softcpu import soc_design  # the SoC with the firmware this checkout builds
            self._texts[key] = soc_design(design.constants, r["arch"])[0]
        else:
            self._texts[key] = design.verilog()[0]
        return self._texts[key]

    def sha256(self, r: dict) -> str:
        """SHA-256 of the Verilog's body (without the header comment): the records made before
        the header existed hashed the same bytes, and a new commit does not make them stale."""
        from ik5r.hdl.provenance import body_sha256
        return body_sha256(self.text(r))


def _router(r: dict) -> str:
    return r.get("router", "router1")  # the records made before the option used router1


def _record_name(r: dict) -> str:
    """``<module>_<config>[_arm-<arm>]_<target>-<device>.json``: records of the arm of record keep
    the names they had before arms were part of the design point."""
    arm = r.get("arm")
    suffix = "" if arm in (None, SEED_ARM) else f"_arm-{arm}"
    return f"{r['module']}_{r['config']}{suffix}_{r['target']}-{r['device']}.json"


def collect(build: Path, sweep: Path, records: Path, docs: Path, verilog: VerilogOfCheckout) -> list[str]:
    """Copy this machine's measurements into ``records`` (see the module docstring); returns what
    was written."""
    from ik5r.hdl.provenance import body_sha256

    written = []
    synth_dir = records / "synth"
    for path in sorted(build.glob("synth/*/result.json"), key=lambda p: p.stat().st_mtime):
        r = json.loads(path.read_text())
        # Runs at other nextpnr seeds (robustness checks) are not the design point's figure.
        # A run that did not fit its device is a measurement too (no Fmax, fits_device false).
        placed = r.get("fmax_mhz") is not None or (r.get("fits_device") is False and r.get("pnr_error"))
        if r.get("config") not in SHIPPED or r.get("seed", 1) != 1 or not placed:
            continue
        design = path.parent / "design.v"
        if not design.exists() or body_sha256(design.read_text()) != verilog.sha256(r):
            continue
        record = {k: v for k, v in r.items() if k not in LOCAL_KEYS}
        record["verilog_sha256"] = verilog.sha256(r)
        if r.get("arm"):      # the arm file's numbers now (limits do not enter the Verilog yet)
            from ik5r.core.arm import load_arm
            record["arm_sha256"] = load_arm(r["arm"]).dh_sha256()
        record["measured_at"] = path.stat().st_mtime
        target = synth_dir / _record_name(r)
        if target.exists() and json.loads(target.read_text()).get("measured_at", 0) >= record["measured_at"]:
            continue
        synth_dir.mkdir(parents=True, exist_ok=True)
        target.write_text(json.dumps(record, indent=1, sort_keys=True) + "\n")
        written.append(str(target))
    written += _other_seeds(build, synth_dir, verilog)
    if (sweep / "sweep.json").exists():
        records.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(sweep / "sweep.json", records / "sweep.json")
        written.append(str(records / "sweep.json"))
        docs.mkdir(parents=True, exist_ok=True)
        for plot in PLOTS:
            if (sweep / plot).exists():
                shutil.copyfile(sweep / plot, docs / plot)
                written.append(str(docs / plot))
    for path in sorted(build.glob("firmware/*.json")):
        target = records / "firmware" / path.name
        if target.exists() and _measured_at(target) >= _measured_at(path):
            continue    # an older run (another worktree's build/, say) never replaces a newer record
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(path, target)
        written.append(str(target))
    for name in ("bench.json", "bench.md", "bench_arms.json", "bench_arms.md"):
        if (build / "bench" / name).exists():
            records.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(build / "bench" / name, records / name)
            written.append(str(records / name))
    return written


def _measured_at(path: Path) -> float:
    """When a firmware record was measured: its ``measured_at``, or for records made before the
    key, the file's modification time."""
    return json.loads(path.read_text()).get("measured_at", path.stat().st_mtime)


def _other_seeds(build: Path, synth_dir: Path, verilog: VerilogOfCheckout) -> list[str]:
    """The Fmax of the runs at other nextpnr seeds (robustness checks) of a recorded design point
    (same Verilog, clock constraint, placer and router), added to its record as ``fmax_mhz_by_seed``."""
    from ik5r.hdl.provenance import body_sha256

    runs = {}
    for path in build.glob("synth/*/result.json"):
        r = json.loads(path.read_text())
        design = path.parent / "design.v"
        if r.get("config") not in SHIPPED or r.get("fmax_mhz") is None or not design.exists():
            continue
        sha = body_sha256(design.read_text())
        if sha == verilog.sha256(r):
            key = (_record_name(r), sha, r.get("freq_target_mhz"), r.get("placer"), _router(r))
            runs.setdefault(key, {})[str(r.get("seed", 1))] = round(r["fmax_mhz"], 1)
    written = []
    for (name, *point), by_seed in runs.items():
        target = synth_dir / name
        record = json.loads(target.read_text()) if target.exists() else {}
        if (record.get("verilog_sha256"), record.get("freq_target_mhz"), record.get("placer"),
                _router(record)) != tuple(point):
            continue
        by_seed = dict(sorted({**record.get("fmax_mhz_by_seed", {}), **by_seed,
                               "1": round(record["fmax_mhz"], 1)}.items(), key=lambda kv: int(kv[0])))
        if len(by_seed) > 1 and by_seed != record.get("fmax_mhz_by_seed"):
            record["fmax_mhz_by_seed"] = by_seed
            target.write_text(json.dumps(record, indent=1, sort_keys=True) + "\n")
            written.append(str(target))
    return written


def synth_table(records: Path, verilog: VerilogOfCheckout) -> tuple[list[str], list[str]]:
    """The synthesis table from the records whose Verilog is this checkout's, and the names of
    the records left out."""
    rows, stale = [], []
    for path in sorted((records / "synth").glob("*.json")):
        r = json.loads(path.read_text())
        if _current(r, verilog):
            rows.append(r)
        else:
            stale.append(path.name)
    rows = [r for r in rows if r.get("arm", SEED_ARM) == SEED_ARM]   # other arms: arms_table
    if not rows:
        return ["No synthesis results yet: run `ik5r synth` (see above)."], stale
    rows.sort(key=lambda r: (r["config"], r["block"], r["arch"]))
    lines = ["| block | arch | primitives | config | device | LUTs | FFs | DSPs | BRAMs | Fmax (MHz) | latency | "
             "cycles/result | results/s |", "| --- | --- | --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in rows:
        lines.append(f"| {r['block']} | {_arch_label(r)} | {r.get('dsp', Dsp.GENERIC)} | {r['config']} | {r['target']}-{r['device']}"
                     f"{' speed ' + str(r['speed_grade']) if r.get('speed_grade') else ' (in context)'}"
                     f"{' (does not fit)' if r.get('fits_device') is False else ''} | {_num(r.get('luts'))} | {_num(r.get('ffs'))} | "
                     f"{_num(r.get('dsps'))} | {_num(r.get('brams'))} | {_num(r.get('fmax_mhz'), '{:.1f}')} | "
                     f"{_num(r.get('latency_cycles'))} | {_num(r.get('cycles_per_result'), '{:,.1f}' if (r.get('cycles_per_result') or 0) % 1 else '{:,.0f}')} | "
                     f"{_num(r.get('results_per_second'), '{:.3g}')} |")
    for r in rows:
        if r.get("fmax_mhz_by_seed"):
            seeds, freq = r["fmax_mhz_by_seed"], r.get("freq_target_mhz")
            constraint = f" and {freq:g} MHz constraint" if freq else ""
            lines += ["", f"{r['block']} {_arch_label(r)} {r['config']} on the {r['target']}-{r['device']}: Fmax "
                      f"{', '.join(f'{v:.1f}' for v in seeds.values())} MHz at nextpnr seeds "
                      f"{', '.join(seeds)} (same Verilog{constraint}; the table gives seed 1)."]
    for r in rows:
        if _router(r) != "router1":
            lines += ["", f"{r['block']} {r['arch']} {r['config']} on the {r['target']}-{r['device']}: routed "
                      f"with nextpnr's {_router(r)} (the other rows: router1)."]
    return lines, stale


def _current(r: dict, verilog: VerilogOfCheckout) -> bool:
    """Whether the record's Verilog is what this checkout generates (a soft CPU record needs
    the cross compiler to tell: without it, the record counts as not current)."""
    from .softcpu import SoftCpuError

    try:
        return r.get("verilog_sha256") == verilog.sha256(r)
    except SoftCpuError:
        return False


def bench_table(records: Path) -> list[str]:
    path = records / "bench.md"
    return path.read_text().rstrip().splitlines() if path.exists() else ["No benchmark yet: run `make bench`."]


def arms_part(records: Path) -> list[str]:
    """Any arm (issue 17): the numeric solver's bench, and the seed papers' tables beside ik5r's."""
    from .seedtables_report import tables

    bench, seeds = records / "bench_arms.md", records / "arms.json"
    lines = bench.read_text().rstrip().splitlines() if bench.exists() else ["No bench yet: run `make bench`."]
    if seeds.exists():
        lines += ["", "Details, assumptions and plots: [docs/arms.md](docs/arms.md).", "",
                  *tables(json.loads(seeds.read_text())).replace("### ", "#### ").splitlines()]
    return lines


def sweep_part(records: Path) -> list[str]:
    from .sweep_record import RECORD_FILE, SweepRecord

    path = records / RECORD_FILE
    if not path.exists():
        return ["No sweep yet: run `ik5r sweep -o build/sweep`."]
    sweep = SweepRecord.read(path)
    points = sweep.points
    lines = [f"![{plot}](docs/results/{plot})" for plot in PLOTS if (records.parent / plot).exists()]
    if sweep.meta.get("note"):      # a caveat kept with the record (e.g. points of an older core)
        lines += ["", f"**{sweep.meta['note']}**"]
    lines += ["", "| block | arch | width | LUTs | DSPs | Fmax (MHz) | max position error (cm) | "
              "RMS position error (cm) | Pareto |", "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | --- |"]
    for p in sorted(points, key=lambda p: (p["block"], p["arch"], p["width"])):
        lines.append(f"| {p['block']} | {p['arch']} | {p['width']} | {_num(p.get('luts'))} | {_num(p.get('dsps'))} | "
                     f"{_num(p.get('fmax_mhz'), '{:.1f}')} | {_num(p.get('position_err_max_cm'), '{:.3g}')} | "
                     f"{_num(p.get('position_err_rms_cm'), '{:.3g}')} | {'yes' if p.get('pareto') else ''} |")
    return lines


def section(records: Path, verilog: VerilogOfCheckout, boards: BoardOfCheckout) -> tuple[str, list[str]]:
    synth, stale = synth_table(records, verilog)
    builds, stale_boards = board_builds(records, boards)
    stale += stale_boards
    parts = [BEGIN, "", "*Generated by `python -m ik5r.tools.results` from the records in `docs/results/records/`; "
             "do not edit by hand.*", "",
             "### Speed (`make bench`)", "", *bench_table(records), "",
             "### Any serial arm: numeric IK (`make bench`, `python -m ik5r.tools.seedtables`)", "", *arms_part(records), "",
             "### Synthesis (`ik5r synth`, Yosys + nextpnr, out of context)", "", *synth, "",
             "### Your arm in hardware (`ik5r synth --arm`, `python -m ik5r.tools.arm_accuracy`)", "",
             *arms_table(records, lambda r: _current(r, verilog)), "",
             *routes_part(records, lambda r: _current(r, verilog)), "",
             "### On a board (`ik5r board`, `ik5r solve --solver board`)", "", *board_part(records, builds), "",
             "### Word-length sweep (`ik5r sweep`)", "", *sweep_part(records), "", END]
    return "\n".join(parts), stale


def regmap_section(text: str) -> str:
    """``text`` with the IK peripheral's register table (between :data:`REGMAP_BEGIN` and
    :data:`REGMAP_END`, when present) generated from the register map."""
    from ik5r.core.regmap_out import markdown_table

    if REGMAP_BEGIN not in text or REGMAP_END not in text:
        return text
    head, rest = text.split(REGMAP_BEGIN, 1)
    _, tail = rest.split(REGMAP_END, 1)
    return f"{head}{REGMAP_BEGIN}\n\n{markdown_table()}\n{REGMAP_END}{tail}"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m ik5r.tools.results", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--build", default="build", help="where ik5r synth and make bench wrote")
    parser.add_argument("--sweep", default="build/sweep", help="the sweep's output folder")
    parser.add_argument("--readme", default="README.md")
    parser.add_argument("--no-collect", action="store_true",
                        help="render from the records as they are (copy nothing from --build)")
    args = parser.parse_args(argv)
    readme = Path(args.readme)
    text = readme.read_text()
    if BEGIN not in text or END not in text:
        raise SystemExit(f"{readme}: no {BEGIN} ... {END} markers")
    docs = readme.parent / "docs" / "results"
    records = docs / "records"
    verilog = VerilogOfCheckout()
    if not args.no_collect:
        for path in collect(Path(args.build), Path(args.sweep), records, docs, verilog):
            print(f"recorded {path}")
    body, stale = section(records, verilog, BoardOfCheckout())
    for name in stale:
        rerun = "ik5r board --record" if name.startswith("board/") else "ik5r synth"
        print(f"left out {name}: its Verilog is not what this checkout generates (re-run {rerun})")
    head, rest = text.split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    readme.write_text(regmap_section(head + body + tail))
    print(f"{readme}: results section regenerated")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
