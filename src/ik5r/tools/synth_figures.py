"""The figures of a synthesis run, from the tools' outputs: cell counts (Yosys ``stat -json``),
utilisation and Fmax (nextpnr's report, or its log when the design did not fit), the critical
path. Pure functions of those files' contents; :mod:`ik5r.tools.synth` runs the tools.
"""

from __future__ import annotations

import re
from pathlib import Path

from ik5r.core.modes import Target


def _overflow(log_path: Path) -> str | None:
    """The nextpnr message saying the design does not fit the device, if that is why it failed."""
    if not log_path.is_file():
        return None
    for line in log_path.read_text(errors="replace").splitlines():
        low = line.lower()
        if "error" in low and ("utilisation" in low or "utilization" in low or "exceed" in low
                               or "too many" in low or "unable to place" in low):
            return line.strip()
    return None


def _log_utilisation(log_path: Path) -> dict | None:
    """``{"utilization": {cell: {"used", "available"}}}`` from nextpnr's "Device utilisation"
    lines (written before placement, so also there when the design does not fit)."""
    util = {}
    if log_path.is_file():
        for line in log_path.read_text(errors="replace").splitlines():
            m = re.match(r"Info:\s+(\w+):\s+(\d+)/\s*(\d+)\s+\d+%", line)
            if m:
                util[m.group(1)] = {"used": int(m.group(2)), "available": int(m.group(3))}
    return {"utilization": util} if util else None


def _overused(log_path: Path) -> str | None:
    """"<cell>: N of M used" for the first cell type nextpnr's utilisation lines show beyond the
    device (the design cannot be placed), else None."""
    util = _log_utilisation(log_path)
    for cell, use in (util or {}).get("utilization", {}).items():
        if use["used"] > use["available"]:
            return f"{cell}: {use['used']} of {use['available']} used (nextpnr stopped before placing)"
    return None


#: Router1 progress reports (one per 1,000 iterations) with no new low of the arcs left to route
#: after which the run is a livelock: every run placed so far reached a new low in every report.
STALL_REPORTS = 50


def _router_stalled(log_path: Path, reports: int = STALL_REPORTS) -> str | None:
    """The livelock of nextpnr's router1 (two nets ripping each other up for ever: an SA
    placement of the iCE40 UP5K's compact core did it) as a message, else None."""
    if not log_path.is_file():
        return None
    left = [int(m.group(1)) for m in re.finditer(r"Info:\s+\d+\s+\|\s+\d+\s+\d+\s+\|\s+-?\d+\s+-?\d+\s+\|"
                                                 r"\s+(\d+)\|", log_path.read_text(errors="replace"))]
    if len(left) <= reports or min(left[-reports:]) < min(left[:-reports]):
        return None
    return (f"nextpnr's router1 routed no further in {reports * 1000:,} iterations "
            f"({left[-1]:,} arcs left): a livelock")


def _cell_counts(stat: dict) -> dict:
    design = stat.get("design") or next(iter(stat.get("modules", {}).values()), {})
    return {str(k): int(v) for k, v in design.get("num_cells_by_type", {}).items()}


def _critical_path(report: dict) -> dict | None:
    """The worst clk -> clk path of a nextpnr report: totals and its steps (cell / net names)."""
    paths = [p for p in report.get("critical_paths", [])
             if p.get("from", "").endswith("clk") and p.get("to", "").endswith("clk")]
    if not paths:
        return None
    steps = paths[0]["path"]
    total = sum(s.get("delay", 0.0) for s in steps)
    kinds = {}
    for s in steps:
        kinds[s["type"]] = kinds.get(s["type"], 0.0) + s.get("delay", 0.0)
    compact = []
    for s in steps:
        if not s.get("delay"):
            continue  # zero-delay hops inside carry chains
        name = s.get("net") or f"{s['from']['cell']}.{s['from']['port']}->{s['to']['port']}"
        compact.append({"type": s["type"], "ns": round(s.get("delay", 0.0), 3), "name": name})
    return {"total_ns": round(total, 3), "logic_ns": round(kinds.get("logic", 0.0), 3),
            "routing_ns": round(kinds.get("routing", 0.0), 3),
            "from_cell": steps[0]["from"]["cell"], "to_cell": steps[-1]["to"]["cell"],
            "steps": compact}


def _figures(target: str, cells: dict, report: dict | None) -> dict:
    used = {k: v.get("used", 0) for k, v in (report or {}).get("utilization", {}).items()}
    avail = {k: v.get("available", 0) for k, v in (report or {}).get("utilization", {}).items()}
    util = {k: {"used": used[k], "available": avail[k]} for k in used if used[k]}
    if target == Target.ECP5:
        lut4 = cells.get("LUT4", 0)
        carry = cells.get("CCU2C", 0)
        # TRELLIS_COMB: LUT4 sites occupied after packing (logic LUTs, both halves of each carry
        # cell, route-throughs); without P&R, estimate as LUT4 + 2 x CCU2C.
        luts = used.get("TRELLIS_COMB", lut4 + 2 * carry)
        ffs = used.get("TRELLIS_FF", cells.get("TRELLIS_FF", 0))
        dsps = cells.get("MULT18X18D", 0) + cells.get("ALU54B", 0)
        brams = cells.get("DP16KD", 0)
        lutram = cells.get("TRELLIS_DPR16X4", 0)
    else:
        lut4 = cells.get("SB_LUT4", 0)
        carry = cells.get("SB_CARRY", 0)
        luts = used.get("ICESTORM_LC", lut4)
        ffs = sum(v for k, v in cells.items() if k.startswith("SB_DFF"))
        dsps = cells.get("SB_MAC16", 0)
        brams = cells.get("SB_RAM40_4K", 0)
        lutram = 0
    fit = all(used[k] <= avail[k] for k in used) if report else None
    return {"luts": luts, "lut4": lut4, "carry": carry, "ffs": ffs, "dsps": dsps, "brams": brams,
            "lutram": lutram, "utilisation": util, "fits_device": fit, "cells": cells}


def _fmax(report: dict | None) -> float | None:
    if not report:
        return None
    clocks = report.get("fmax", {})
    entry = clocks.get("clk") or next(iter(clocks.values()), None)
    return float(entry["achieved"]) if entry else None
