"""The README's per-arm table: accuracy records (:mod:`ik5r.tools.arm_accuracy`) beside the
compact core's synthesis records of the same arm (``ik5r synth --arm``), one row per arm.

A synthesis record counts for an arm only when it names that arm (a record without ``arm`` is
of the arm of record) and its Verilog is what this checkout generates for it: a record made for
one arm never stands for another.
"""

from __future__ import annotations

import json
from pathlib import Path

from ik5r.core.arm import SEED_ARM
from ik5r.core.modes import Block, CoreArch, Target

#: The design point of the table's area, Fmax and cycles.
CORE = {"block": Block.IK, "arch": CoreArch.COMPACT, "config": "q32w", "target": Target.ECP5, "device": "25k"}


def _num(value, fmt="{:,.0f}") -> str:
    return "–" if value is None else fmt.format(value)


def _synth_of(records: Path, arm: str, current) -> dict | None:
    for path in sorted((records / "synth").glob("*.json")):
        r = json.loads(path.read_text())
        if all(r.get(k) == v for k, v in CORE.items()) and r.get("arm", SEED_ARM) == arm and current(r):
            return r
    return None


def arms_table(records: Path, current) -> list[str]:
    """Markdown lines; ``current(record)``: its Verilog is this checkout's."""
    rows = [json.loads(p.read_text()) for p in sorted((records / "arm_accuracy").glob(f"*_{CORE['config']}.json"))]
    if not rows:
        return ["No per-arm records yet: run `python -m ik5r.tools.arm_accuracy`."]
    lines = ["Compact IK core, config q32w, ECP5-25k (`ik5r synth --block ik --arch compact --config q32w "
             "--device 25k --freq 80 --arm NAME`); tool-point error of the fixed-point IK against float64 "
             "on random reachable poses; C, scalar and vectorised model compared on every output field.", "",
             "| arm | reach (cm) | max tool-point error (cm) | / reach | RMS (cm) | C/scalar/vector differing fields "
             "| LUT4 | Fmax (MHz) | cycles per pose |",
             "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    rows.sort(key=lambda r: (r["arm"] != SEED_ARM, r["arm"]))
    for r in rows:
        s = _synth_of(records, r["arm"], current) or {}
        lines.append(f"| {r['arm']} | {r['reach_cm']:.2f} | {r['position_err_max_cm']:.3g} | "
                     f"{r['position_err_max_per_reach']:.2g} | {r['position_err_rms_cm']:.3g} | "
                     f"{r['software_differing_fields']} | {_num(s.get('lut4'))} | "
                     f"{_num(s.get('fmax_mhz'), '{:.1f}')} | {_num(s.get('cycles_per_result'))} |")
    return lines
