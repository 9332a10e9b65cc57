"""The Verilator C++ bulk harness (``src/ik5r/tools/testbench/harness.py``): a block streamed from
a file of words, every output bit compared with the model, and the comparison able to fail.

The default run builds one small block (sqrt, pipelined, q18: a C++ build of ~1 min at -O0) and
streams it at full rate and under random idles and back-pressure, and the compact IK core of a
shipped arm other than the arm of record (its own Verilog against its own model); the slow set
soaks both IK cores of every shipped config through the same path (the pipelined core 10**7
poses each, ``IK5R_SOAK_POSES`` to change; the compact core 1/500 of that). The cocotb runs of
the cores (``tests/test_cocotb_core.py``) keep the stream protocol's checks: resets in traffic,
idles and back-pressure against the full monitor. The netlist the harness verilates (the design
through Yosys's ``SIM_PASSES``) is proved equivalent to the design: the small block by default,
the compact IK core (q18) and the pipelined atan2 block (q32w) in the slow set.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from ik5r.core.modes import Dsp
from ik5r.tools.testbench.harness import verilated_name
from ik5r.tools.testbench.portmap import Field, Stream

pytestmark = pytest.mark.sim

SMALL = ("sqrt", "pipelined", "q18")


def small():
    from ik5r.tools.testbench.runner import sim_design
    return sim_design(*SMALL)
SOAK_POSES = int(os.environ.get("IK5R_SOAK_POSES", str(10**7)))


def _need_verilator():
    from ik5r.tools.testbench.runner import simulator_missing
    missing = simulator_missing("verilator")
    if missing:
        pytest.skip(missing)


def test_verilated_names():
    assert verilated_name("o__ready") == "o___05Fready"
    assert verilated_name("clk") == "clk"
    assert verilated_name("i_a__b__c") == "i_a___05Fb___05Fc"


def test_pack_words_round_trip():
    stream = Stream("v", "r", "p", 75, {"a": Field("a", 0, 38, True), "b": Field("b", 38, 1, False),
                                        "c": Field("c", 39, 36, True)})
    rng = np.random.default_rng(5)
    cols = {name: rng.integers(f.lo, f.hi + 1, 500) for name, f in stream.fields.items()}
    cols["a"][:2], cols["c"][:2] = (stream.fields["a"].lo, stream.fields["a"].hi), (-1, 0)
    words = stream.pack_words(cols)
    assert words.shape == (500, 3) and words.dtype == np.uint32
    assert int(words[:, 2].max()) < 1 << 11          # nothing above the 75 bits
    back = stream.unpack_words(words)
    for name in cols:
        np.testing.assert_array_equal(back[name], cols[name])
    assert all(int(h, 16) == stream.pack({n: int(cols[n][j]) for n in cols})
               for j, h in enumerate(stream.pack_hex(cols)[:50]))


@pytest.mark.parametrize("pattern", ["full", "random"])
def test_harness_matches_model(pattern):
    _need_verilator()
    from ik5r.tools.testbench.harness import run_harness
    r = run_harness(small(), vectors=3000, seed=11, pattern=pattern, chunk=1024, cflags="-O0")
    assert r["mismatches"] == 0, r["first_mismatch"]
    assert r["tag_errors"] == 0 and r["hold_violations"] == 0 and r["stale_outputs"] == 0
    assert r["vectors"] >= 3000 and r["harness"]["vectors"] == r["vectors"]
    cycles = r["harness"]["cycles"]
    # Full rate: one item per clock after the fill; random: idles and stalls cost cycles.
    assert (cycles < r["vectors"] + 4 * (r["latency_cycles_portmap"] + 2100)) if pattern == "full" \
        else cycles > 1.2 * r["vectors"]


def test_harness_runs_the_ecp5_primitives():
    """The ``--dsp ecp5`` Verilog (the netlist that is placed: CCU2C chains and MULT18X18D, with
    their models) through the harness: every bit equals the model."""
    _need_verilator()
    from ik5r.tools.testbench.harness import run_harness
    from ik5r.tools.testbench.runner import sim_design
    r = run_harness(sim_design(*SMALL, dsp=Dsp.ECP5), vectors=3000, seed=12, pattern="random", cflags="-O0", jobs=1)
    assert r["mismatches"] == 0, r["first_mismatch"]
    assert r["tag_errors"] == 0 and r["hold_violations"] == 0 and r["stale_outputs"] == 0
    assert r["vectors"] >= 3000 and r["dsp"] == Dsp.ECP5


def test_ccu2c_adder_is_its_function():
    """The CCU2C adder module the ECP5 Verilog carries equals ``SUB ? A - B : A + B`` at every
    width up to 80 (a SAT proof on the CCU2C model), so the harness may simulate its function;
    an adder wrong in one bit of one width is refused."""
    from ik5r.hdl.datapath.ecp5 import ecp5_add_sub_verilog
    from ik5r.tools.testbench.simnetlist import ADD_SUB_FUNCTION, prove_add_sub
    chain = ecp5_add_sub_verilog()
    proved, said = prove_add_sub(chain, range(2, 81))
    assert proved, said
    wrong = ADD_SUB_FUNCTION.replace("A - B : A + B", "A - B : A + B + (WIDTH == 37 ? {A[30], 30'd0} & {B[30], 30'd0} : 0)")
    assert wrong != ADD_SUB_FUNCTION
    proved, said = prove_add_sub(chain, [36, 37], wrong)
    assert not proved and "proof did fail" in said


def test_harness_reports_a_wrong_bit(monkeypatch):
    """One expected bit flipped in the model's answer: the run counts exactly that item."""
    _need_verilator()
    from ik5r.tools.testbench import harness
    from ik5r.tools.testbench.job import Job

    original = Job.expected

    def flipped(self, inputs, check_scalar=256):
        exp = original(self, inputs, check_scalar)
        role = next(iter(exp))
        exp[role] = exp[role].copy()
        exp[role][7] ^= 1
        return exp

    monkeypatch.setattr(Job, "expected", flipped)
    r = harness.run_harness(small(), vectors=500, seed=12, pattern="full", cflags="-O0")
    assert r["mismatches"] == 1 and r["first_mismatch"]["index"] == 7


#: A register fed by a sum, in the style of the designs' Verilog: a process with a case.
TINY = """module m(clk, sel, a, b, q);
  input clk;
  input sel;
  input [7:0] a;
  input [7:0] b;
  output [8:0] q;
  reg [8:0] r = 9'h000;
  reg [8:0] \\r$next ;
  always @* begin
    \\r$next  = r;
    casez (sel)
      1'h1: \\r$next  = { a[7], a } + { b[7], b };
      default: \\r$next  = { a[7], a } - { b[7], b };
    endcase
  end
  always @(posedge clk) r <= \\r$next ;
  assign q = r;
endmodule
"""


def test_equivalence_proof_can_fail(tmp_path):
    """The proof the simulation netlist rests on: a lowered module is proved equal to its source,
    and the same netlist with one operator changed is not."""
    from ik5r.tools.testbench.simnetlist import prove_equivalent, simulation_text
    source = tmp_path / "m.v"
    source.write_text(TINY)
    lowered = simulation_text(source, "m")
    assert "always @*" not in lowered.read_text()          # the process is gone: lowered
    ok, said = prove_equivalent(source, lowered, "m")
    assert ok, said
    wrong = tmp_path / "wrong.v"
    wrong.write_text(lowered.read_text().replace(" - ", " + ", 1))
    assert wrong.read_text() != lowered.read_text()
    ok, said = prove_equivalent(source, wrong, "m")
    assert not ok and "unproven" in said


@pytest.mark.parametrize("design", [pytest.param(SMALL, id="-".join(SMALL)),
                                    pytest.param(("ik", "compact", "q18"), id="ik-compact-q18",
                                                 marks=pytest.mark.slow),
                                    # The pipelined IK core's proof is beyond YoWASP's Yosys (it
                                    # stops with a Wasm exception after ~18 min at q18); its blocks:
                                    pytest.param(("atan2", "pipelined", "q32w"), id="atan2-pipelined-q32w",
                                                 marks=pytest.mark.slow)])
def test_simulation_netlist_is_the_design(design, tmp_path):
    """The text the harness verilates (the design's Verilog through Yosys's ``SIM_PASSES``, then
    the replications) is proved equivalent to the design's Verilog: every port and register on
    every clock."""
    from ik5r.tools.testbench.simnetlist import prove_equivalent, simulation_text
    from ik5r.tools.testbench.portmap import load_portmap
    from ik5r.tools.testbench.runner import generate_sources, sim_design
    vpath, jpath = generate_sources(sim_design(*design), tmp_path)
    top = load_portmap(jpath).top
    ok, said = prove_equivalent(vpath, simulation_text(vpath, top), top)
    assert ok, said


#: Every shipped config of both IK cores, and the netlist of record that is placed (the pipelined
#: q32w core with the ECP5 primitives). The pipelined core takes a pose per clock, so its soak
#: runs at the simulator's cycle rate; the compact core takes one per ~800 cycles: a soak of its
#: own size (10**7 of its poses would be ~8e9 cycles a config).
SOAK = [pytest.param(arch, c, SOAK_POSES if arch == "pipelined" else max(1, SOAK_POSES // 500), Dsp.GENERIC,
                     id=f"ik-{arch}-{c}", marks=pytest.mark.slow)
        for arch in ("pipelined", "compact") for c in ("q18", "q24", "q32", "q32w")]
SOAK.append(pytest.param("pipelined", "q32w", SOAK_POSES, Dsp.ECP5, id="ik-pipelined-dspecp5-q32w",
                         marks=pytest.mark.slow))


@pytest.mark.parametrize("arch,config,poses,dsp", SOAK)
def test_soak_ik_core(arch, config, poses, dsp):
    """The IK core soaked through the harness (random idles and back-pressure): every bit of
    every pose, in chunks of 2**20."""
    _need_verilator()
    from ik5r.tools.testbench.harness import run_harness
    from ik5r.tools.testbench.runner import sim_design
    r = run_harness(sim_design("ik", arch, config, dsp=dsp), vectors=poses, seed=2025, pattern="random")
    assert r["mismatches"] == 0, r["first_mismatch"]
    assert r["tag_errors"] == 0 and r["hold_violations"] == 0 and r["stale_outputs"] == 0
    assert r["vectors"] >= poses


#: A shipped arm other than the arm of record: its own Verilog (constants, formats' bounds), its
#: own model; the compact core keeps the C++ build short.
OTHER_ARM = "youbot-arm"


def test_harness_on_another_arm():
    """The harness simulates the design's arm: the Verilog it built names that arm, and every bit
    of every pose (random and directed, random idles and back-pressure) equals that arm's model."""
    _need_verilator()
    import json

    from ik5r.tools.testbench.harness import harness_dir, run_harness
    from ik5r.tools.testbench.runner import sim_design
    design = sim_design("ik", "compact", "q32w", arm=OTHER_ARM)
    r = run_harness(design, vectors=300, seed=13, pattern="random", cflags="-O0", jobs=1)
    assert r["arm"] == OTHER_ARM and design.arm_suffix in str(harness_dir(design))
    assert json.loads((harness_dir(design) / "src" / "ik.json").read_text())["arm"]["name"] == OTHER_ARM
    assert r["mismatches"] == 0, r["first_mismatch"]
    assert r["tag_errors"] == 0 and r["hold_violations"] == 0 and r["stale_outputs"] == 0
    assert r["vectors"] >= 300 and r["harness"]["vectors"] == r["vectors"]


def test_cycle_limit_is_sized_by_the_cycles_per_result():
    """A chunk of the compact core (~830 cycles a pose) gets more cycles than its poses need even
    with every other cycle idle, and far more than a limit sized for one item per clock."""
    from ik5r.tools.testbench.harness import cycle_limit
    from ik5r.tools.testbench.portmap import PortMap

    def pm(latency, per_result):
        return PortMap(top="t", ports={}, i=None, o=None, clk="clk", rst="rst", latency_cycles=latency,
                       cycles_per_result=per_result, raw={})

    items = 1500
    compact, one_per_clock = cycle_limit(items, pm(830, 830)), cycle_limit(items, pm(830, 1))
    assert compact >= 4 * items * 830 and compact > 100 * one_per_clock // 2
    assert cycle_limit(items, pm(300, None)) == cycle_limit(items, pm(300, 1))


def test_cli_harness_passes_the_arm(monkeypatch, tmp_path):
    """``ik5r sim --harness --arm NAME``: the harness gets the design of that arm and the stream
    run's options (the bit-exact run of such a design is the test above); its counts are merged."""
    import json

    from ik5r.tools.cli import main
    from ik5r.tools.testbench import harness, runner

    seen = {}
    counts = {"mismatches": 0, "first_mismatch": None, "field_mismatches": {"q1": 0}, "tag_errors": 0,
              "stale_outputs": 0, "hold_violations": 0, "max_error_lsb": 0.5, "rms_error_lsb": 0.1}

    def stream_run(design, sim, **kw):
        seen["stream"] = design
        return dict(counts, vectors=10, latency_cycles=800, cycles_per_result=800, latency_cycles_portmap=800,
                    cycles_per_result_portmap=800, arm=design.arm.name, block="ik", arch=design.arch,
                    config=design.config.name, simulator=sim, stream={"vectors": 10}, bulk=None,
                    build_seconds=0.0, build_dir="", waves=None, log="")

    def bulk_run(design, **kw):
        seen["bulk"], seen["kw"] = design, kw
        return dict(counts, vectors=300, harness={"vectors": 300, "vectors_per_second": 1.0}, error_items=300,
                    build_seconds=0.0)

    monkeypatch.setattr(runner, "run_block", stream_run)
    monkeypatch.setattr(harness, "run_harness", bulk_run)
    out = tmp_path / "sim.json"
    assert main(["sim", "--block", "ik", "--arch", "compact", "--arm", OTHER_ARM, "--simulator", "verilator",
                 "--harness", "--vectors", "300", "--tag-width", "6", "--json", str(out), "-q"]) == 0
    assert seen["bulk"] is seen["stream"] and seen["bulk"].arm.name == OTHER_ARM
    assert seen["bulk"].options.tag_width == 6 and seen["kw"]["vectors"] == 300
    doc = json.loads(out.read_text())
    assert doc["arm"] == OTHER_ARM and doc["vectors"] == 310 and doc["bulk"]["simulator"] == "verilator-harness"


def test_harness_binary_comes_from_the_cache(monkeypatch, tmp_path):
    """A build folder without the binary (another checkout, a cleaned build/) gets it from the
    cache keyed by the Verilog's body, the main and the flags: no second build."""
    _need_verilator()
    from ik5r.tools.testbench import harness

    design = small()
    # A folder of its own: the checkout's build folder may hold a binary the cache never saw.
    monkeypatch.setattr(harness, "harness_dir", lambda d: tmp_path / "first")
    first, _, _ = harness.build_harness(design, cflags="-O0")      # built, or found in the cache

    def no_build():
        raise AssertionError("built again")

    monkeypatch.setattr(harness, "harness_dir", lambda d: tmp_path / "fresh")
    monkeypatch.setattr(harness, "_build_lock", no_build)
    binary, pm, seconds = harness.build_harness(design, cflags="-O0")
    assert seconds == 0.0 and binary.parent.parent == tmp_path / "fresh"
    assert binary.read_bytes() == first.read_bytes() and pm.top


def test_harness_main_is_built_with_the_flags(monkeypatch, tmp_path):
    """``cflags`` reaches the harness's own C++ (the stimulus and the compare run every clock) and
    the model's run-time code through verilated.mk's ``OPT_FAST``/``OPT_GLOBAL``; the code run
    once (``OPT_SLOW``) is built at -O0, so ``-CFLAGS`` (after them on every line) holds no level;
    a flag that is not one option is refused."""
    from ik5r.tools.testbench import harness

    seen = {}

    class Stop(Exception):
        pass

    real_run = harness.subprocess.run

    def verilator(cmd, **kw):
        if cmd[0] != "verilator" or "--build-jobs" not in cmd:
            return real_run(cmd, **kw)
        seen["env"], seen["cmd"] = kw["env"], cmd
        raise Stop                    # before anything is built

    monkeypatch.setattr(harness, "harness_dir", lambda d: tmp_path)
    monkeypatch.setattr(harness, "_cache_key", lambda *a: "no-cache")
    monkeypatch.setattr(harness, "_from_cache", lambda key, binary: False)
    monkeypatch.setattr(harness.subprocess, "run", verilator)
    with pytest.raises(Stop):
        harness.build_harness(small(), cflags="-O3")
    make_vars = seen["env"]["MAKEFLAGS"].split()
    assert {"OPT_FAST=-O3", "OPT_GLOBAL=-O3", "OPT_SLOW=-O0"} <= set(make_vars)
    cflags = seen["cmd"][seen["cmd"].index("-CFLAGS") + 1]
    assert not any(flag.startswith("-O") for flag in cflags.split())
    with pytest.raises(ValueError, match="one compiler option"):
        harness.build_harness(small(), cflags="-O2 -g")
