"""The bit-accuracy section: C vs scalar model vs vectorised model vs HDL, per output field.

The three software solvers are run on the same words (random reachable poses and the directed edge
set of ``ik5r.firmware_model.vectors``); the hardware results come from cocotb runs (``src/ik5r/tools/testbench``), which
compare every output field of every item with the vectorised model.
"""

from __future__ import annotations

import numpy as np

from ik5r.core.fxconfig import Constants
from ik5r.core.modes import Block

from .html import Section, esc, para, table

FIELDS = ("q1", "q2", "q3", "q4", "q5", "status")
#: The scalar model is the slow one: it sees this many rows of the pose set.
SCALAR_ROWS = 4000


def _field_mismatches(a, b) -> dict:
    (q_a, st_a), (q_b, st_b) = a, b
    counts = {f"q{j + 1}": int((q_a[:, j] != q_b[:, j]).sum()) for j in range(5)}
    counts["status"] = int((st_a != st_b).sum())
    return counts


def software_agreement(k: Constants, poses) -> dict:
    """Per-field mismatch counts between the C solver, the vectorised and the scalar model."""
    from ik5r.firmware_model import csolver, model, vector

    args = poses.args()
    c_out = csolver.solver(k).solve_batch(*args)
    v_out = vector.solve_batch(k, *args)
    rows = min(SCALAR_ROWS, len(poses))
    # The scalar rows: the edge set's end of the pose set plus the start of the random part.
    idx = np.unique(np.concatenate([np.arange(rows // 2), np.arange(len(poses) - rows // 2, len(poses))]))
    s_out = model.solve_batch(k, *(v[idx] for v in args))
    sub = lambda out: (out[0][idx], out[1][idx])   # noqa: E731
    return {
        "poses": len(poses), "scalar_rows": int(len(idx)),
        "pairs": [
            {"a": "C solver", "b": "vectorised model", "items": len(poses),
             "field_mismatches": _field_mismatches(c_out, v_out)},
            {"a": "scalar model", "b": "vectorised model", "items": int(len(idx)),
             "field_mismatches": _field_mismatches(s_out, sub(v_out))},
            {"a": "C solver", "b": "scalar model", "items": int(len(idx)),
             "field_mismatches": _field_mismatches(sub(c_out), s_out)},
        ],
    }


def hdl_rows(sim_results: list[dict]) -> list[dict]:
    """The figures of each cocotb run that the report shows."""
    keys = ("block", "arch", "config", "simulator", "vectors", "mismatches", "field_mismatches",
            "first_mismatch", "tag_errors", "stale_outputs", "latency_cycles", "cycles_per_result",
            "max_error_lsb", "rms_error_lsb", "bulk_vectors_per_second")
    return [{key: r.get(key) for key in keys} for r in sim_results]


def total_mismatches(data: dict) -> int:
    software = sum(sum(p["field_mismatches"].values()) for p in data["software"]["pairs"])
    hardware = sum(int(r["mismatches"] or 0) + int(r["tag_errors"] or 0) + int(r["stale_outputs"] or 0)
                   for r in data["hdl"])
    return software + hardware


def section(k: Constants, software: dict, sim_results: list[dict]) -> Section:
    data = {"config": k.cfg.name, "software": software, "hdl": hdl_rows(sim_results)}
    data["total_mismatches"] = total_mismatches(data)
    ok = data["total_mismatches"] == 0
    parts = [para(
        f"Every output word and status bit of the fixed-point IK, compared between its four "
        f"implementations. Zero mismatches expected everywhere; total found: "
        f"<span class=\"{'ok' if ok else 'bad'}\">{data['total_mismatches']:,}</span>.")]
    rows = [(f"{p['a']} vs {p['b']}", p["items"], *(p["field_mismatches"][f] for f in FIELDS))
            for p in software["pairs"]]
    for r in data["hdl"]:
        if r["block"] == Block.IK:
            fields = r["field_mismatches"] or {}
            rows.append((f"HDL core ({r['arch']}, {r['simulator']}) vs vectorised model", r["vectors"],
                         *(fields.get(f, "–") for f in FIELDS)))
    parts.append(table(("pair", "poses", *FIELDS), rows,
                       caption=f"IK: three-way agreement of C, bit-accurate model and HDL ({k.cfg.name}; "
                               f"random reachable poses + the directed edge set)"))
    block_rows = []
    for r in data["hdl"]:
        fields = r["field_mismatches"] or {}
        per_field = ", ".join(f"{name} {count}" for name, count in fields.items()) or "–"
        block_rows.append((f"{r['block']} {r['arch']}", r["simulator"], r["vectors"], r["mismatches"],
                           per_field, r["tag_errors"], r["stale_outputs"], r["latency_cycles"],
                           r["cycles_per_result"], r["max_error_lsb"], r["rms_error_lsb"],
                           r["bulk_vectors_per_second"]))
    parts.append(table(("block", "simulator", "vectors", "mismatches", "per output field", "tag errors",
                        "stale after reset", "latency (cycles)", "cycles/result", "max err vs f64 (LSB)",
                        "RMS err (LSB)", "vectors/s"), block_rows,
                       caption="HDL under cocotb against the bit-accurate model (random idles, random "
                               "back-pressure with long stalls, a reset in mid-traffic)"))
    firsts = [(f"{r['block']} {r['arch']} {r['simulator']}", esc(str(r["first_mismatch"])))
              for r in data["hdl"] if r["first_mismatch"]]
    if firsts:
        parts.append(table(("run", "first mismatch"), firsts, caption="First mismatches"))
    parts.append(para("Errors against float64 are those of the block's own function (atan2, rotate, sqrt, "
                      "acos) in output LSB; for the IK core the task-space figures of the quantisation "
                      "section apply: the hardware gives the same bits as the model there."))
    return Section("bit_accuracy", "Bit accuracy: C, model and HDL", "\n".join(parts), data)


def summary_lines(data: dict) -> list[str]:
    lines = [f"bit accuracy ({data['config']}): {data['total_mismatches']} mismatching items in total"]
    for p in data["software"]["pairs"]:
        lines.append(f"  {p['a'] + ' vs ' + p['b']:<40} {p['items']:>9,} poses  "
                     f"{sum(p['field_mismatches'].values())} mismatches")
    for r in data["hdl"]:
        lines.append(f"  HDL {r['block']:<6} {r['arch']:<10} {r['simulator']:<9} {r['vectors']:>9,} vectors  "
                     f"{r['mismatches']} mismatches  latency {r['latency_cycles']}  "
                     f"cycles/result {r['cycles_per_result']}")
    return lines
