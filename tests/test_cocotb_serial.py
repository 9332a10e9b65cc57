"""cocotb runs of the compact IK core's word-serial wrapper (``SerialIK``, hdl/sequenced/serial.py) as
synthesised for the iCE40 UP5K (16-bit beats, ``ik5r.tools.synth.ICE40_BEAT_BITS``), against the
bit-accurate model (``ik5r sim --block ik --arch compact --serial 16``; src/ik5r/tools/testbench/serial.py).

A beat driver serialises each pose into its 28 beats, a beat monitor reassembles the 6 output
words (every q bit, the status, the tag, and the padding bits, which must be 0), an in-order
scoreboard compares them with ``model.ik_solve`` / ``vector.solve_batch``; random idles before any
input beat, random back-pressure with long stalls on the output beats, a reset in the middle of
traffic with an output beat held; latency (first input beat to last output beat) and cycles per
pose at full rate measured against the wrapper's port map.

The core takes ~600-750 clocks per pose, so the default run is small: every 16th directed pose
(25) + 4 random, q18 with an 8-bit tag on Icarus. The slow set adds q32w on Verilator with no tag,
the design ``ik5r synth --block ik --arch compact --target ice40`` places (tag width 0; in the default
run that design is simulated in Verilator inside the iCEBreaker's top level, tests/test_board_link.py),
and runs the whole directed set + 60 random poses on both simulators, q18, q32 and q32w.
"""

from __future__ import annotations

import pytest

from ik5r.core.fxconfig import constants, load_config
from ik5r.firmware_model.vectors import directed_poses
from ik5r.tools.synth import ICE40_BEAT_BITS

CASE_KEYS = ("config", "size", "sim")     # sim_pool (conftest.py)
#: (random poses, every n-th directed pose) of a run.
SIZES = {"small": (4, 16), "large": (60, 1)}
#: Tag width by simulator: the Icarus runs check the tag, the Verilator runs simulate the placed
#: design (no tag).
TAG_WIDTH = {"icarus": 8, "verilator": 0}
DEFAULT = {("q18", "small", "icarus")}
#: Run in the slow set only.
SMALL_SLOW = {("q32w", "small", "verilator")}

CASES = [
    pytest.param(c, size, s, id=f"serial{ICE40_BEAT_BITS}-{c}-{size}-{s}",
                 marks=() if (c, size, s) in DEFAULT else (pytest.mark.slow,))
    for s in ("icarus", "verilator") for c in ("q18", "q32", "q32w") for size in SIZES
    if size == "large" or (c, size, s) in DEFAULT | SMALL_SLOW
]


def run_case(config, size, sim):
    from ik5r.tools.testbench.runner import run_block, sim_design

    random_poses, stride = SIZES[size]
    design = sim_design("ik", "compact", config, serial=ICE40_BEAT_BITS, tag_width=TAG_WIDTH[sim])
    return run_block(design, sim, stream_vectors=random_poses, bulk_vectors=0, seed=2024,
                     cflags="-O0", edge_stride=stride)


@pytest.mark.sim
@pytest.mark.parametrize("config,size,sim", CASES)
def test_serial_wrapper_matches_model(sim_pool, config, size, sim):
    r = sim_pool((config, size, sim))
    random_poses, stride = SIZES[size]
    assert r["mismatches"] == 0, f"first mismatch: {r['first_mismatch']} (log: {r['log']})"
    assert r["tag_errors"] == 0 and r["stale_outputs"] == 0 and r["hold_violations"] == 0
    assert r["serial"] == ICE40_BEAT_BITS and r["bulk"] is None
    s = r["stream"]
    assert s is not None and not s.get("aborted"), f"the cocotb test did not finish (log: {r['log']})"
    directed = len(directed_poses(constants(load_config(config)))[::stride])
    assert r["vectors"] == s["vectors"] == random_poses + directed
    assert set(r["field_mismatches"]) == {"q1", "q2", "q3", "q4", "q5", "status"}
    # A reset while poses were in flight and an output beat was held; the stream rule checked.
    assert s["resets"] == 1 and s["reset_while_held"] is True and s["held_cycles"] > 0
    # ... with a pose half sent (its beats dropped, the pose sent again with a new tag).
    assert s["beats_dropped_by_reset"]["input"] > 0
    assert r["latency_cycles"] == r["latency_cycles_portmap"]
    assert r["cycles_per_result"] == r["cycles_per_result_portmap"]


#: Misuses of ``ik5r sim --serial`` and the line each must give (not parametrised: the module's
#: parametrised tests are the simulation cases of ``sim_pool``).
CLI_MISUSES = [
    (["--block", "atan2", "--serial", "16"], "use it with --block ik --arch compact"),
    (["--block", "ik", "--arch", "pipelined", "--serial", "16"], "use it with --block ik --arch compact"),
    (["--block", "ik", "--arch", "compact", "--serial", "16", "--stream-vectors", "0"], "must be > 0"),
]


def test_cli_serial_needs_the_compact_core(capsys):
    """``ik5r sim --serial`` on anything but the compact IK core, or with nothing to run: one line,
    exit 2, before any generation or build."""
    from ik5r.tools.cli import main

    for argv, message in CLI_MISUSES:
        assert main(["sim", *argv]) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and message in err[0], (argv, err)


def test_cli_serial_beat_bits_checked(capsys):
    from ik5r.tools.cli import main

    with pytest.raises(SystemExit) as exc:
        main(["sim", "--block", "ik", "--arch", "compact", "--serial", "0"])
    assert exc.value.code == 2 and "argument --serial: must be in [1, 32]" in capsys.readouterr().err


#: The bench's self-test: 8-bit beats (3 per q18 word, 6 padding bits in each word's last beat),
#: its own build directory; 4 directed poses + 1 random per run.
SELFTEST = dict(config="q18", sim="icarus", serial=8, stream_vectors=1, edge_stride=100)


def _selftest_run(fault):
    from ik5r.tools.testbench.runner import run_block, sim_design, simulator_missing

    missing = simulator_missing(SELFTEST["sim"])
    if missing:
        pytest.fail(f"{missing} (CI installs both simulators)", pytrace=False)
    opts = {k: v for k, v in SELFTEST.items() if k not in ("config", "sim", "serial")}
    design = sim_design("ik", "compact", SELFTEST["config"], serial=SELFTEST["serial"])
    return run_block(design, SELFTEST["sim"], bulk_vectors=0, seed=5, fault=fault, **opts)


@pytest.mark.sim
def test_serial_bench_catches_a_padding_bit():
    """Another beat width runs clean; a bit set above a word's fields fails the run."""
    clean = _selftest_run(None)
    assert clean["mismatches"] == 0, clean["first_mismatch"]
    assert clean["latency_cycles"] == clean["latency_cycles_portmap"]
    assert clean["stream"]["resets"] == 1
    padding = _selftest_run({"kind": "flip", "at": 2, "bit": 7})     # q1's top beat: word bit 23
    assert padding["mismatches"] >= 1 and padding["first_mismatch"]["kind"] == "padding"
    assert "q1 word" in padding["first_mismatch"]["got"]


@pytest.mark.sim
@pytest.mark.slow
def test_serial_bench_catches_a_lost_beat():
    """A beat lost on the way out (q2's first): the pose's words never complete; the run stops
    with no progress (after ~46,000 clocks) and fails."""
    drop = _selftest_run({"kind": "drop", "at": 3})
    assert drop["mismatches"] >= 1 and drop["first_mismatch"]["kind"] == "aborted"
    assert drop["stream"]["aborted"] is True
