"""Three routes to the IK on one FPGA, from the records: the C solver on a soft CPU (rv32im and
rv32i), the compact IK core and the pipelined IK core (``python -m ik5r.tools.results`` renders it).

A route's area and Fmax come from its synthesis record (``records/synth``), a soft CPU's cycles
per pose from its ``ik5r firmware`` record (``records/firmware``: mean over the poses, measured
cycle by cycle); a core's cycles per pose and latency from its synthesis record. Derived
columns: latency = cycles of one pose / Fmax; poses/s = Fmax / cycles per pose; per 1,000 LUT4 =
poses/s / (LUT4 / 1,000). The verdict lines are computed from the same numbers.
"""

from __future__ import annotations

import json
from pathlib import Path

CONFIG = "q32w"
#: (label, synth record, firmware record or None): the routes in table order.
ROUTES = (
    ("soft CPU: VexRiscv, rv32im (Nios II/f class)", "ik5r_soc_vexriscv_{c}_ecp5-25k", "vexriscv_rv32im_{c}"),
    ("soft CPU: VexRiscv, rv32i code (software multiply)", "ik5r_soc_vexriscv_{c}_ecp5-25k", "vexriscv_rv32i_{c}"),
    ("soft CPU: VexRiscv_Min, rv32i (Nios II/e class)", "ik5r_soc_vexriscv_min_{c}_ecp5-25k", "vexriscv_min_rv32i_{c}"),
    ("soft CPU: VexRiscv, rv32im, on the 85k", "ik5r_soc_vexriscv_{c}_ecp5-85k", "vexriscv_rv32im_{c}"),
    ("compact IK core", "ik5r_ik_compact_{c}_ecp5-25k", None),
    ("compact IK core, 16 x 31-bit product step (2 DSPs)", "ik5r_ik_wide_product1_compact_{c}_ecp5-25k", None),
    ("compact IK core, two poses a program", "ik5r_ik_poses2_compact_{c}_ecp5-25k", None),
    ("compact IK core, two poses a program, limb registers in the DSP (--dsp ecp5)",
     "ik5r_ik_dspecp5_poses2_compact_{c}_ecp5-25k", None),
    ("compact IK core, two poses a program, 16 x 31-bit product step in 2 DSPs (--dsp ecp5)",
     "ik5r_ik_dspecp5_poses2_wide_product1_compact_{c}_ecp5-25k", None),
    ("pipelined IK core (ECP5 DSP + carry primitives)", "ik5r_ik_dspecp5_pipelined_{c}_ecp5-85k", None),
    ("pipelined IK core, 2 micro-rotations per stage (ECP5 primitives)",
     "ik5r_ik_dspecp5_rotations_per_stage2_pipelined_{c}_ecp5-85k", None),
    ("pipelined IK core, 4 micro-rotations per stage (ECP5 primitives)",
     "ik5r_ik_dspecp5_rotations_per_stage4_pipelined_{c}_ecp5-85k", None),
    ("pipelined IK core, a fabric register after each DSP (ECP5 primitives)",
     "ik5r_ik_dspecp5_dsp_output_regs1_pipelined_{c}_ecp5-85k", None),
)
#: The fourth route: the soft CPU calling the compact core on its bus (ik5r firmware --peripheral),
#: and the SoC running the C it is compared with.
PERIPH_ROUTE = ("soft CPU + compact core: VexRiscv rv32im, ik5r_hw_solve on the bus",
                "ik5r_soc_vexriscv_compact_{c}_ecp5-25k", "vexriscv_rv32im_{c}_periph_compact")


def _load(path: Path):
    return json.loads(path.read_text()) if path.is_file() else None


def _firmware_current(fw: dict) -> bool:
    """Whether a firmware record ran the SoC this checkout simulates (a record made before the
    record kept its Verilog's hash, or one the cross compiler's absence leaves unknown: not)."""
    from .softcpu import SoftCpuError, firmware_verilog_sha256

    if "verilog_sha256" not in fw:
        return False
    try:
        return fw["verilog_sha256"] == firmware_verilog_sha256(fw)
    except SoftCpuError:
        return False


def route_rows(records: Path, is_current, firmware_current=_firmware_current) -> list[dict]:
    """One dict per route whose records exist: figures and derived columns; a row is current
    when its synthesis record and its firmware record (if any) are of this checkout's Verilog."""
    rows = []
    for label, synth_name, fw_name in (*ROUTES, PERIPH_ROUTE):
        s = _load(records / "synth" / f"{synth_name.format(c=CONFIG)}.json")
        fw = _load(records / "firmware" / f"{fw_name.format(c=CONFIG)}.json") if fw_name else None
        if s is None or not s.get("fmax_mhz") or (fw_name and fw is None):
            continue
        if fw and fw.get("peripheral"):     # the hardware call, timed from the CPU's side
            cycles = latency_cycles = fw["call_cycles"]["mean"]
        elif fw:
            cycles, latency_cycles = fw["cycles_per_solve"]["mean"], fw["cycles_per_solve"]["mean"]
        else:
            cycles, latency_cycles = s["cycles_per_result"], s["latency_cycles"]
        fmax = s["fmax_mhz"]
        poses = fmax * 1e6 / cycles
        # A route placed with another router than the others' router1 says so.
        router = s.get("router", "router1")
        label += "" if router == "router1" else f", routed by nextpnr's {router}"
        rows.append({"label": label, "device": f"{s['target']}-{s['device']}", "luts": s["luts"],
                     "ffs": s["ffs"], "dsps": s["dsps"], "brams": s["brams"], "fmax": fmax,
                     "cycles": cycles, "latency_us": latency_cycles / fmax, "poses": poses,
                     "per_kilo_lut": poses / (s["luts"] / 1000),
                     "current": is_current(s) and (fw is None or firmware_current(fw)),
                     "mismatches": None if fw is None else fw["mismatches"],
                     "vectors": None if fw is None else fw["vectors"],
                     "cpu": bool(fw) and not fw.get("peripheral"), "periph": fw if fw and fw.get("peripheral") else None,
                     "firmware": fw_name})
    return rows


def _fmt(value, digits=0) -> str:
    return f"{value:,.{digits}f}"


def _ratio(a: float, b: float) -> str:
    return f"{a / b:,.1f}x" if a >= b else f"1/{b / a:,.1f}"


def _stale(row: dict) -> str:
    return "" if row["current"] else " (record of other Verilog)"


def _verdict(rows: list[dict]) -> list[str]:
    """One line per IK core against the rv32im soft CPU on the same device (else the 25k)."""
    cpus = {r["device"]: r for r in rows if r["cpu"] and "rv32im" in r["label"]}
    lines = []
    for core in (r for r in rows if not r["cpu"] and not r["periph"]):
        cpu = cpus.get(core["device"]) or cpus.get("ecp5-25k")
        if cpu is None:
            continue
        per_lut = "beats" if core["per_kilo_lut"] > cpu["per_kilo_lut"] else "does NOT beat"
        # A record of other Verilog is no claim about this checkout's core: said where it is used.
        who = "it" if core["current"] and cpu["current"] else "that record"
        lines.append(
            f"- **{core['label']}**{_stale(core)} on the {core['device']} vs the rv32im soft CPU{_stale(cpu)} "
            f"on the {cpu['device']}"
            f"{' (no soft CPU record on the ' + core['device'] + ')' if cpu['device'] != core['device'] else ''}: "
            f"{_ratio(core['luts'], cpu['luts'])} the LUT4, {_fmt(core['dsps'])} vs {_fmt(cpu['dsps'])} DSPs, "
            f"{_fmt(core['brams'])} vs {_fmt(cpu['brams'])} block RAMs, {_ratio(core['fmax'], cpu['fmax'])} "
            f"the clock, {_ratio(core['cycles'], cpu['cycles'])} the cycles per pose, "
            f"{_ratio(core['latency_us'], cpu['latency_us'])} the latency, {_ratio(core['poses'], cpu['poses'])} "
            f"the poses/s and {_ratio(core['per_kilo_lut'], cpu['per_kilo_lut'])} the poses/s per 1,000 LUT4: "
            f"{who} {per_lut} the soft CPU per LUT.")
    return lines


def routes_part(records: Path, is_current, firmware_current=_firmware_current) -> list[str]:
    """The README subsection: the table and the verdict."""
    rows = route_rows(records, is_current, firmware_current)
    head = [f"### {'Four' if any(r['periph'] for r in rows) else 'Three'} routes: firmware on a soft CPU "
            f"vs the IK cores ({CONFIG})", ""]
    if not rows:
        return head + ["No records yet: run `make firmware` and `ik5r synth --block cpu --device 25k`."]
    lines = head + [
        "| route | device | LUT4 | FF | DSP | BRAM | Fmax (MHz) | cycles/pose | latency (us) | poses/s "
        "| poses/s per 1,000 LUT4 |",
        "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in rows:
        lines.append(f"| {r['label']}{_stale(r)} | {r['device']} | {_fmt(r['luts'])} | {_fmt(r['ffs'])} | "
                     f"{_fmt(r['dsps'])} | {_fmt(r['brams'])} | {_fmt(r['fmax'], 1)} | {_fmt(r['cycles'], 1 if not r['cpu'] and r['cycles'] % 1 else 0)} | "
                     f"{_fmt(r['latency_us'], 2)} | {_fmt(r['poses'])} | {_fmt(r['per_kilo_lut'])} |")
    checked = []  # one entry per firmware record (the 85k row reuses the 25k's)
    for r in rows:
        if r["cpu"] and all(r["firmware"] != c["firmware"] for c in checked):
            checked.append(r)
    notes = ["", "Soft CPU cycles per pose: mean over the poses of `ik5r firmware` (random reachable + "
             "directed set; read the pose from RAM, `ik5r_solve`, write the result), cycle-accurate "
             "in Verilator; " + "; ".join(f"{r['label'].split(': ')[1]}: {r['vectors']:,} poses, "
                                          f"{r['mismatches']} mismatches" for r in checked) + ". "
             "The SoC's block RAMs hold the 16 KiB program/data RAM and the CPU's caches and register file.",
             "", *_verdict(rows), *_periph_lines(rows)]
    return lines + notes


def _periph_lines(rows: list[dict]) -> list[str]:
    """The fourth route against the same SoC running the C: solves/s, time per call, the CPU's
    free cycles per solve, the bus's share."""
    cpu = next((r for r in rows if r["cpu"] and r["device"] == "ecp5-25k" and "rv32im" in r["label"]
                and "85k" not in r["label"]), None)
    lines = []
    for r in (r for r in rows if r["periph"]):
        fw = r["periph"]
        over = fw["bus_overhead_cycles"]
        line = (f"- **{r['label']}**{_stale(r)}: {fw['vectors']:,} poses, {fw['differing_words_hw_vs_sw']} "
                f"words differ between the hardware and the software path of the same firmware "
                f"({fw['mismatches']} mismatches vs the model and the host C); a call takes "
                f"{_fmt(fw['call_cycles']['mean'], 1)} cycles on average (max {_fmt(fw['call_cycles']['max'])}), "
                f"{_fmt(r['latency_us'], 2)} us, {_fmt(r['poses'])} solves/s; the core's latency is "
                f"{_fmt(fw['core_latency_cycles'])} cycles, the bus's overhead {_fmt(over['mean'], 1)} on "
                f"average ({100 * fw['bus_share']:.1f}% of the call, max {_fmt(over['max'])}, the first "
                f"call of a run with cold caches); with the start/poll or interrupt path the CPU has the "
                f"core's {_fmt(fw['core_latency_cycles'])} cycles per solve free for its control loop")
        if cpu is not None:
            line += (f"; {_ratio(r['poses'], cpu['poses'])} the solves/s of the same SoC running the C"
                     f"{_stale(cpu)}, for {_ratio(r['luts'], cpu['luts'])} its LUT4")
        lines.append(line + ".")
    return lines
