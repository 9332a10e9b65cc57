"""The hardware section: the committed synthesis records (docs/results/records/synth) of a config.

Each record is one ``ik5r synth`` run (Yosys + nextpnr, out of context): latency, cycles per pose,
LUT4 sites, flip-flops, DSPs, block RAMs, Fmax and the device. Records are shown for the config's
name only when their config numbers are the config's own (a record of an older q32w is left out
and said so).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

from ik5r.core.fxconfig import FixedConfig, parse_config
from ik5r.core.modes import Arch, Block, Dsp

from .html import Section, esc, para, table
from .provenance import config_hash

BLOCK_ORDER = (Block.IK, Block.ATAN2, Block.ROTATE, Block.SQRT, Block.ACOS)


def records_dir() -> Path:
    """docs/results/records of the checkout ik5r runs from (absent in an installed copy)."""
    return Path(__file__).resolve().parents[4] / "docs" / "results" / "records"


def _record_config_hash(record: dict) -> str | None:
    import tomllib

    try:
        return config_hash(parse_config(tomllib.loads(record["config_toml"]), "<record>"))
    except (KeyError, ValueError, tomllib.TOMLDecodeError):
        return None


def records_for(cfg: FixedConfig, directory: Path | None = None) -> tuple[list[dict], list[str]]:
    """(records of this config, names of records of the same name but other numbers)."""
    directory = directory or records_dir() / "synth"
    own, stale = [], []
    wanted = config_hash(cfg)
    for path in sorted(directory.glob("*.json")) if directory.is_dir() else []:
        try:
            record = json.loads(path.read_text())
        except (OSError, ValueError):
            continue
        if record.get("config") != cfg.name:
            continue
        if _record_config_hash(record) == wanted:
            own.append(dict(record, record_file=path.name))
        else:
            stale.append(path.name)
    order = {b: i for i, b in enumerate(BLOCK_ORDER)}
    own.sort(key=lambda r: (order.get(r.get("block"), 99), r.get("arch") != Arch.PIPELINED, r.get("device", "")))
    return own, stale


def row_of(r: dict) -> dict:
    """The figures of one record the report shows (JSON and table)."""
    return {
        "block": r.get("block"), "arch": r.get("arch"), "primitives": r.get("dsp", Dsp.GENERIC),
        "device": f"{r.get('target')} {r.get('device')} ({r.get('package')}, speed {r.get('speed_grade')})",
        "latency_cycles": r.get("latency_cycles"), "cycles_per_pose": r.get("cycles_per_result"),
        "lut4_sites": r.get("luts"), "ffs": r.get("ffs"), "dsps": r.get("dsps"), "brams": r.get("brams"),
        "fmax_mhz": r.get("fmax_mhz"), "results_per_second": r.get("results_per_second"),
        "latency_us": (r["latency_ns"] / 1000 if r.get("latency_ns") else None),
        "clock_target_mhz": r.get("freq_target_mhz"), "timing_met": r.get("timing_met"),
        "measured_utc": (time.strftime("%Y-%m-%d", time.gmtime(r["measured_at"]))
                         if r.get("measured_at") else None),
        "record": r.get("record_file"),
    }


def section(cfg: FixedConfig, directory: Path | None = None) -> Section:
    records, stale = records_for(cfg, directory)
    rows = [row_of(r) for r in records]
    header = ("block", "arch", "primitives", "device", "latency (cycles)", "cycles/pose", "LUT4 sites",
              "FFs", "DSPs", "BRAMs", "Fmax (MHz)", "poses/s", "latency (µs)", "record")
    cells = [(r["block"], r["arch"], r["primitives"], r["device"], r["latency_cycles"], r["cycles_per_pose"],
              r["lut4_sites"], r["ffs"], r["dsps"], r["brams"], r["fmax_mhz"], r["results_per_second"],
              r["latency_us"], r["record"]) for r in rows]
    parts = [para(
        f"Synthesis records of {esc(cfg.name)} committed in docs/results/records/synth (ik5r synth: Yosys "
        "+ nextpnr, out of context; LUT4 sites are nextpnr's TRELLIS_COMB, carry cells included; "
        "Fmax from nextpnr's timing analysis). Re-measure with <code>ik5r synth --block ik --config "
        f"{esc(cfg.name)}</code> and <code>python -m ik5r.tools.results</code>.")]
    if rows:
        parts.append(table(header, cells, caption=f"Hardware figures of {cfg.name}"))
    else:
        parts.append(para(f"No committed synthesis record of {esc(cfg.name)} "
                          f"({'not in a checkout' if not records_dir().is_dir() else 'none measured yet'})."))
    if stale:
        parts.append(para("Left out, their config numbers are not this config's: " + esc(", ".join(stale)) + "."))
    data = {"records_dir": "docs/results/records/synth", "rows": rows, "stale_records": stale}
    return Section("hardware", "Hardware: latency, resources, Fmax", "\n".join(parts), data)
