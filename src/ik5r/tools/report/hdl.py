"""``ik5r report --hdl``: the report with the hardware simulated (what ``make demo`` shows).

1. Verilog of the pipelined IK core and of every block into ``DIR/verilog/`` with their port maps
   (JSON), the very files the simulations below use;
2. the IK core under cocotb (random idles, back-pressure, a mid-traffic reset) on ``hdl_poses``
   random reachable poses plus the directed edge set, every output bit against the bit-accurate
   model, and each block on ``block_vectors``; each run's result JSON into ``DIR/sim/``;
3. the C solver, the scalar model and the vectorised model on the same kind of poses;
4. the quantisation report with the bit-accuracy section and a section linking the files above.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

from ik5r.core.arm import Arm, load_arm
from ik5r.core.fxconfig import FixedConfig, load_config
from ik5r.core.modes import Arch, Block

from . import bitaccuracy
from .build import build_report
from .html import Section, esc, jsonable, para

#: The arithmetic blocks (the IK core is written first, on its own).
BLOCKS = tuple(b for b in Block if b != Block.IK)


def write_verilog(cfg: FixedConfig, arm: Arm, out_dir: Path) -> list[dict]:
    """Verilog and port map of the IK core and every block, as simulated (pipelined, with the
    testbench's tag field); [{block, arch, module, verilog, portmap, design}]. ``ik5r verilog``
    writes the other architectures and tag widths."""
    from ik5r.tools.design import Design
    from ik5r.tools.testbench.runner import DEFAULT_TAG_WIDTH

    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for block in (Block.IK, *BLOCKS):
        design = Design.resolve(block, Arch.PIPELINED, config=cfg, arm=arm, tag_width=DEFAULT_TAG_WIDTH)
        text, pmap = design.verilog()
        verilog, portmap = out_dir / f"{pmap['module']}.v", out_dir / f"{pmap['module']}.json"
        verilog.write_text(text)
        portmap.write_text(json.dumps(pmap, indent=2) + "\n")
        written.append({"block": block, "arch": Arch.PIPELINED, "module": pmap["module"], "design": design,
                        "verilog": verilog, "portmap": portmap,
                        "latency_cycles": pmap.get("latency_cycles"),
                        "cycles_per_result": pmap.get("cycles_per_result")})
    return written


def simulate(modules: list[dict], out_dir: Path, simulator: str, hdl_poses: int,
             block_vectors: int, progress: bool, log) -> list[dict]:
    """Each module of ``modules`` under cocotb; each result JSON into ``out_dir``."""
    from ik5r.tools.testbench.runner import run_block

    out_dir.mkdir(parents=True, exist_ok=True)
    results = []
    for m in modules:
        block = m["block"]
        count, what = (hdl_poses, "random reachable poses") if block == Block.IK else (block_vectors, "vectors")
        log(f"{block} under cocotb on {simulator}: {count:,} {what} + the edge set")
        result = run_block(m["design"], simulator, stream_vectors=min(count, 500), bulk_vectors=count, seed=1,
                           progress=progress and block == Block.IK, verilog=m["verilog"], portmap=m["portmap"],
                           cflags="-O0")   # as the test suite builds them: ~4x faster to compile, one cache
        name = f"{block}_{result['arch']}_{simulator}.json"
        (out_dir / name).write_text(json.dumps(jsonable(result), indent=2) + "\n")
        results.append(dict(result, json_file=f"sim/{name}"))
    return results


def files_section(modules: list[dict], sims: list[dict]) -> Section:
    """Links to the generated Verilog, port maps and simulation results."""
    by_module = {}
    for r in sims:
        by_module[(r["block"], r["arch"])] = r
    rows = []
    for m in modules:
        sim = by_module.get((m["block"], m["arch"]))
        link = lambda href: f'<a href="{esc(href)}">{esc(Path(href).name)}</a>'  # noqa: E731
        rows.append((m["block"], m["arch"], link(f"verilog/{m['module']}.v"), link(f"verilog/{m['module']}.json"),
                     link(sim["json_file"]) if sim else "–", m["latency_cycles"], m["cycles_per_result"],
                     (sim["mismatches"] if sim else "–")))
    header = ("block", "arch", "Verilog", "port map", "simulation JSON", "latency (cycles)",
              "cycles/result", "mismatches")
    html_rows = ["<tr>" + "".join(f"<td>{c if isinstance(c, str) else esc(c)}</td>" for c in row) + "</tr>"
                 for row in rows]
    body = ("<table><caption>Generated files</caption><tr>" + "".join(f"<th>{esc(h)}</th>" for h in header)
            + "</tr>\n" + "\n".join(html_rows) + "</table>")
    data = {"modules": [{**{k: v for k, v in m.items() if k != "design"}, "verilog": f"verilog/{m['module']}.v",
                         "portmap": f"verilog/{m['module']}.json"} for m in modules],
            "tag_width": 8,
            "simulations": [r["json_file"] for r in sims]}
    return Section("files", "Generated Verilog, port maps, simulation results", para(
        "The Verilog the report simulated (deterministic: the same config gives the same text; with the "
        "testbench's 8-bit tag field, carried in order beside each item), its port maps (the stream "
        "interface, formats, latency and throughput of each module) and the result of each cocotb run. "
        "<code>ik5r verilog --block all --arch all</code> writes every architecture, with or without tags.") + body, data)


def build_full_report(out_dir, vectors: int = 1_000_000, config=None, arm=None, seed: int = 0, *,
                      hdl: bool = True, hdl_poses: int = 10_000, block_vectors: int = 5_000,
                      simulator: str = "verilator", worst: int = 20, progress: bool = False, log=print):
    """The report, with the HDL simulated when ``hdl``: (JSON doc, summary text, bit-accuracy data)."""
    from ik5r.firmware_model.poses import concat
    from ik5r.firmware_model.vectors import edge_poses, random_poses

    out_dir = Path(out_dir)
    cfg = config if isinstance(config, FixedConfig) else load_config(config)
    arm_ = arm if isinstance(arm, Arm) else load_arm(arm)
    front, extra, bit = [], [], None
    if hdl:
        from ik5r.core.fxconfig import Constants

        t0 = time.perf_counter()
        k = Constants(cfg, arm_)
        log(f"Verilog of every block and the IK core ({cfg.name}, arm {arm_.name}) -> {out_dir / 'verilog'}")
        modules = write_verilog(cfg, arm_, out_dir / "verilog")
        sims = simulate(modules, out_dir / "sim", simulator, hdl_poses, block_vectors, progress, log)
        log("C solver vs scalar model vs vectorised model")
        poses = concat(random_poses(k, max(hdl_poses // 8, 1), seed=1), edge_poses(k))
        section = bitaccuracy.section(k, bitaccuracy.software_agreement(k, poses), sims)
        bit = section.data
        front, extra = [section], [files_section(modules, sims)]
        log(f"HDL part done in {time.perf_counter() - t0:.0f} s")
    log(f"quantisation report on {vectors:,} poses -> {out_dir}")
    doc, summary = build_report(out_dir, vectors=vectors, config=cfg, arm=arm, seed=seed, progress=progress,
                                front_sections=front, extra_sections=extra, worst=worst, simulators=hdl)
    return doc, summary, bit


def hdl_summary(bit: dict) -> list[str]:
    return bitaccuracy.summary_lines(bit)

