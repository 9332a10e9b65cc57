"""A tiny hand-written stream block ("dummy": saturating a + b and a - b) with a port map of the
generator's shape, to test the testbench itself without the Amaranth blocks.

``arch="pipelined"``: ``depth`` register stages with a global stall, one result per cycle.
``arch="iterative"``: one item at a time, ``depth`` cycles each.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .blocks import BLOCKS, BlockSpec


def _sat(v, w):
    lo, hi = -(1 << (w - 1)), (1 << (w - 1)) - 1
    return np.clip(v, lo, hi)


def _vec(x, pm, k):
    w = pm.i.fields["a"].width
    a, b = np.asarray(x["a"], dtype=np.int64), np.asarray(x["b"], dtype=np.int64)
    return {"sum": _sat(a + b, w), "diff": _sat(a - b, w)}


def _scalar(x, pm, k):
    w = pm.i.fields["a"].width
    lo, hi = -(1 << (w - 1)), (1 << (w - 1)) - 1
    return {"sum": max(lo, min(hi, x["a"] + x["b"])), "diff": max(lo, min(hi, x["a"] - x["b"]))}


def _random(rng, n, pm, k):
    f = pm.i.fields["a"]
    return {"a": rng.integers(f.lo, f.hi, n, endpoint=True), "b": rng.integers(f.lo, f.hi, n, endpoint=True)}


def _edges(pm, k):
    f = pm.i.fields["a"]
    vals = [0, 1, -1, f.lo, f.hi]
    a, b = zip(*[(p, q) for p in vals for q in vals])
    return {"a": np.array(a), "b": np.array(b)}


def _err(x, got, pm, k):
    w = pm.i.fields["a"].width
    return np.abs(got["sum"] - _sat(x["a"] + x["b"], w)).astype(np.float64)


BLOCKS["dummy"] = BlockSpec("dummy", {"a": ("a",), "b": ("b",)}, {"sum": ("sum",), "diff": ("diff",)},
                            _vec, _scalar, _random, _edges, _err)


def write_dummy(out_dir: str | Path, width: int = 18, tag_width: int = 8, arch: str = "pipelined",
                depth: int = 4) -> tuple[Path, Path]:
    """Write dummy.v and dummy.json (port map); returns their paths."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    w, t = width, tag_width
    pi = po = 2 * w + t
    sat = f"""
    function [{w - 1}:0] sat;
        input [{w}:0] v;
        sat = (v[{w}] != v[{w - 1}]) ? {{v[{w}], {{{w - 1}{{~v[{w}]}}}}}} : v[{w - 1}:0];
    endfunction"""
    calc = (f"{{tag_in, sat({{a[{w - 1}], a}} - {{b[{w - 1}], b}}), sat({{a[{w - 1}], a}} + {{b[{w - 1}], b}})}}")
    if arch == "pipelined":
        body = f"""
    reg [{po - 1}:0] data [0:{depth - 1}];
    reg [{depth - 1}:0] v;
    wire adv = !v[{depth - 1}] | o__ready;
    assign i__ready = adv;
    assign o__valid = v[{depth - 1}];
    assign o__payload = data[{depth - 1}];
    integer s;
    always @(posedge clk) begin
        if (rst) v <= 0;
        else if (adv) begin
            v <= {{v[{depth - 2}:0], i__valid}};
            data[0] <= {calc};
            for (s = 1; s < {depth}; s = s + 1) data[s] <= data[s - 1];
        end
    end"""
        latency, cpr = depth, 1
    else:
        body = f"""
    reg busy, done;
    reg [7:0] cnt;
    reg [{po - 1}:0] res;
    assign i__ready = !busy & !done;
    assign o__valid = done;
    assign o__payload = res;
    always @(posedge clk) begin
        if (rst) begin busy <= 0; done <= 0; cnt <= 0; end
        else if (i__valid & i__ready) begin busy <= 1; cnt <= {depth - 1}; res <= {calc}; end
        else if (busy) begin
            if (cnt == 0) begin busy <= 0; done <= 1; end
            cnt <= cnt - 1;
        end else if (done & o__ready) done <= 0;
    end"""
        latency, cpr = depth + 1, depth + 2
    verilog = f"""module dummy (
    input wire clk, input wire rst,
    input wire i__valid, output wire i__ready, input wire [{pi - 1}:0] i__payload,
    output wire o__valid, input wire o__ready, output wire [{po - 1}:0] o__payload
);
    wire signed [{w - 1}:0] a = i__payload[{w - 1}:0];
    wire signed [{w - 1}:0] b = i__payload[{2 * w - 1}:{w}];
    wire [{t - 1}:0] tag_in = i__payload[{2 * w + t - 1}:{2 * w}];{sat}{body}
endmodule
"""
    fields_i = {"a": {"lsb": 0, "width": w, "signed": True, "frac": 0},
                "b": {"lsb": w, "width": w, "signed": True, "frac": 0},
                "tag": {"lsb": 2 * w, "width": t, "signed": False, "frac": None}}
    fields_o = {"sum": {"lsb": 0, "width": w, "signed": True, "frac": 0},
                "diff": {"lsb": w, "width": w, "signed": True, "frac": 0},
                "tag": {"lsb": 2 * w, "width": t, "signed": False, "frac": None}}
    pm = {"block": "dummy", "arch": arch, "top": "dummy",
          "ports": {"clk": {"direction": "input", "width": 1}, "rst": {"direction": "input", "width": 1},
                    "i__valid": {"direction": "input", "width": 1}, "i__ready": {"direction": "output", "width": 1},
                    "i__payload": {"direction": "input", "width": pi},
                    "o__valid": {"direction": "output", "width": 1}, "o__ready": {"direction": "input", "width": 1},
                    "o__payload": {"direction": "output", "width": po}},
          "payload": {"i__payload": fields_i, "o__payload": fields_o},
          "latency_cycles": latency, "cycles_per_result": cpr}
    vpath, jpath = out_dir / "dummy.v", out_dir / "dummy.json"
    vpath.write_text(verilog)
    jpath.write_text(json.dumps(pm, indent=1))
    return vpath, jpath
