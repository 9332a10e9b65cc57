"""The sequenced IK engine (the IK core's ``compact`` arch: hdl/sequenced/isa.py, seq_program.py,
seq_core.py) against the bit-accurate model (``model.solve_batch``).

Three levels: the program on the clock-exact reference interpreter (every directed pose and
hundreds of random ones per config, in seconds), the Amaranth simulation of the engine in its
struct-stream shell (``SequencedIKCore``: exact latency and one pose per program length at full
rate; random input gaps and output back-pressure; the output held), and the word-serial wrapper
(``SerialIK``) with random gaps on both sides. cocotb runs of the Verilog are in
tests/test_cocotb_core.py (arch ``iterative`` = ``compact``).
"""

from __future__ import annotations

import dataclasses
import gc
import itertools
import random
import re

import numpy as np
import pytest
from amaranth.sim import Simulator
from test_ik_core import expected_of, inputs_of, with_tags

from ik5r.core import status as st
from ik5r.core.fxconfig import constants, load_config
from ik5r.firmware_model import model
from ik5r.firmware_model.poses import PoseBatch, concat
from ik5r.firmware_model.vectors import directed_poses, random_poses
from ik5r.hdl.graph.inputs import INPUT_WORDS
from ik5r.hdl.sequenced import asm as seq_asm
from ik5r.hdl.sequenced import isa as seq_isa
from ik5r.hdl.sequenced import machine
from ik5r.hdl.sequenced import shifts as seq_shifts
from ik5r.hdl.generate import generate
from ik5r.hdl.sequenced.engine import STATUS_BITS, SequencedIKCore
from ik5r.hdl.sequenced.serial import SerialIK
from ik5r.hdl.sequenced.program import ik_program
from ik5r.tools.testbench.amaranth_stream import compare, run_stream
from ik5r.tools.testbench.blocks import ik_outputs

TAG_WIDTH = 6
WORD_FIELDS = ("px", "py", "pz", "ax", "ay", "az", "nx", "ny", "nz", "ox", "oy", "oz", "q5_default")


def _k(name):
    return constants(load_config(name))


def _engine_words(fields, i, tag):
    words = [int(fields[name][i]) for name in WORD_FIELDS]
    flags = (int(fields["has_roll"][i]) | int(fields["shoulder_back"][i]) << 1
             | int(fields["elbow_down"][i]) << 2 | tag << 3)
    return words + [flags]


#: The interpreter takes 5-10 CPU s a program: the default run takes q18 (both product steps) and the
#: default core's q32w program; q32's and the q32w wide step's in the slow set.
INTERPRETER_SLOW = {("q32", False), ("q32w", True)}


@pytest.mark.parametrize("cfg, wide", [
    pytest.param(cfg, wide, marks=(pytest.mark.slow,) if (cfg, wide) in INTERPRETER_SLOW else ())
    for cfg, wide in (("q18", False), ("q32", False), ("q32w", False), ("q18", True), ("q32w", True))])
def test_program_on_interpreter(cfg, wide):
    """Every directed pose and 200 random ones (all branches, with and without n, o); also the
    program of the wide product step (16 x 31-bit limb products)."""
    k = _k(cfg)
    prog = ik_program(k, wide_product=wide)
    assert prog.widths.b_limbs == (2 if wide else 1)
    poses = concat(directed_poses(k), random_poses(k, 25, seed=11))
    expected = ik_outputs(k, poses, model.solve_batch)
    fields = poses.fields()
    bad = []
    for i in range(len(poses)):
        out = machine.run(prog, _engine_words(fields, i, i % 64))
        got = {f"q{j + 1}": out[j] for j in range(5)}
        got["status"] = out["status"]
        want = {name: int(expected[name][i]) for name in got}
        if got != want or out["tag"] != i % 64:
            bad.append((i, want, got))
    assert not bad, f"{len(bad)} of {len(poses)} mismatch, first {bad[0]}"


@pytest.mark.slow
def test_two_pose_program_on_interpreter():
    """q32w's program of two poses on the interpreter (q18's: in the core's test, which
    compiles it anyway)."""
    _two_pose_program_on_interpreter(_k("q32w"))


def _two_pose_program_on_interpreter(k):
    """A program of two poses (``poses=2``) runs each pose as the one-pose program does: pose
    i beside pose i + 1, so every run mixes branches, flags and tags (a pose reading the other's
    flags, status or words fails)."""
    prog = ik_program(k, poses=2)
    assert prog.poses == 2 and len(prog.code) < 2 * len(ik_program(k).code)
    poses = concat(directed_poses(k), random_poses(k, 10, seed=12))
    expected = ik_outputs(k, poses, model.solve_batch)
    fields = poses.fields()
    bad = []
    for i in range(len(poses)):
        pair = (i, (i + 1) % len(poses))
        outs = machine.run_poses(prog, [_engine_words(fields, j, j % 64) for j in pair])
        for j, out in zip(pair, outs):
            got = {f"q{n + 1}": out[n] for n in range(5)} | {"status": out["status"]}
            want = {name: int(expected[name][j]) for name in got}
            if got != want or out["tag"] != j % 64:
                bad.append((j, want, got))
    assert not bad, f"{len(bad)} of {2 * len(poses)} mismatch, first {bad[0]}"


def test_program_poses_checked():
    with pytest.raises(ValueError, match="poses must be one of"):
        ik_program(_k("q18"), poses=3)
    with pytest.raises(ValueError, match="takes 2 poses a run"):
        machine.run_poses(ik_program(_k("q18"), poses=2), [[0] * 14])


def _frame_noise(k, poses, seed):
    """The poses with n, o, a moved by up to twice the orientation tolerance, by pose index mod 6:
    |n| off, |o| off, n towards o, or one component of a off (so that each check of
    ``model.frame_is_bad`` alone decides some poses)."""
    rng = np.random.default_rng(seed)
    f = poses.fields()
    vec = {key: np.stack([f[f"{key}{axis}"] for axis in "xyz"], axis=1).astype(float) for key in "noa"}
    count = len(poses)
    e = rng.uniform(-2, 2, (count, 1)) * k.cfg.orientation_tolerance
    mode = np.arange(count) % 6
    vec["n"] += np.where(mode[:, None] == 0, e * vec["n"], 0) + np.where(mode[:, None] == 2, e * vec["o"], 0)
    vec["o"] += np.where(mode[:, None] == 1, e * vec["o"], 0)
    vec["a"] += (mode[:, None] == 3 + np.arange(3)) * e * 2.0 ** k.cfg.frac_unit
    for key in "noa":
        for j, axis in enumerate("xyz"):
            f[f"{key}{axis}"] = np.clip(np.rint(vec[key][:, j]), k.word_min, k.word_max).astype(np.int64)
    return PoseBatch.from_fields(f)


@pytest.mark.parametrize("cfg", ("q18", "q32w"))
def test_program_orientation_checks(cfg):
    """n, o, a near the orientation tolerance (every check of ``model.frame_is_bad`` alone
    decides some poses): the program's status bits are the model's."""
    k = _k(cfg)
    poses = _frame_noise(k, random_poses(k, 50, seed=12), seed=13)
    expected = ik_outputs(k, poses, model.solve_batch)
    bad_orientation = (np.asarray(expected["status"]) & st.BAD_ORIENTATION) != 0
    assert 0.1 < bad_orientation.mean() < 0.9
    prog = ik_program(k)
    fields = poses.fields()
    got = [machine.run(prog, _engine_words(fields, i, 0))["status"] for i in range(len(poses))]
    assert got == [int(v) for v in expected["status"]]


def test_program_is_traced_from_the_one_ik():
    """Every word of the vocabulary ``ik.solve`` uses has a symbolic twin (``fx.*``, ``fw.*``),
    and a branch of the body on a traced value is refused (the body must select)."""
    import ast
    import inspect

    from ik5r.core import ik
    from ik5r.hdl.graph import trace as seq_trace

    used = {(n.value.id, n.attr) for n in ast.walk(ast.parse(inspect.getsource(ik)))
            if isinstance(n, ast.Attribute) and isinstance(n.value, ast.Name) and n.value.id in ("fx", "fw")}
    assert {name for ns, name in used if ns == "fx"} <= set(vars(seq_trace.SymFx))
    assert {name for ns, name in used if ns == "fw"} <= set(vars(seq_trace.SymFw))
    joints, status, graph = seq_trace.trace(_k("q32w"))
    assert len(joints) == 5 and status.leaves
    with pytest.raises(TypeError):
        bool(joints[0] > 0)


def test_program_is_short_and_shared():
    """One program per config; the q32w pose within 774 clocks (720 before issue 31's plane from
    the approach near the base axis, 830 with it; 774 with its v-or-0 as loads, its magnitudes
    as a compare and a negation, two square-root digits a clock and the hill climb's lowered
    priorities; 752 with a load sharing the clock of another block's last read of the
    accumulator and the clips to a format's range as one saturation; 721 with the CORDIC
    vector's normalisations by powers of two; 656 with the rotations of constant vectors
    gained before their quadrant steps; 666 with three normalising shifts, not five: fewer
    LUTs; 657 with the scheduler's swaps of two blocks' priorities; 650 with an atan2's
    zero-vector instructions before its angle's rounding: the CORDIC free sooner), 625 with the
    wide product step; units used side by side."""
    k = _k("q32w")
    prog = ik_program(k)
    assert len(prog.code) <= 650
    assert len(ik_program(k, wide_product=True).code) <= 625
    both = [ins for ins in prog.code if seq_isa.nonzero(ins.cop) and (seq_isa.nonzero(ins.alu) or ins.pick)]
    assert len(both) > 100       # CORDIC micro-rotations beside products and glue
    assert len(ik_program(_k("q18")).code) < len(ik_program(_k("q32")).code) < len(prog.code)


def test_shift_ops_are_the_fewest():
    """An accumulator shift by n is the fewest ops of the three amounts (checked against every
    multiset of them), or refused when none adds up to n."""
    sizes = (3, 4, 32)
    for n in range(1, 80):
        ops = seq_shifts.shift_ops(n, sizes)
        counts = [r for r in range(1, 12)
                  for c in itertools.combinations_with_replacement(sizes, r) if sum(c) == n]
        if not counts:
            assert ops is None, n
            continue
        assert sum(ops) == n and len(ops) == min(counts) and ops == sorted(ops, reverse=True)
    with pytest.raises(ValueError, match="no sum"):
        seq_asm.Asm(_k("q18"), acc_shifts=(3, 4, 32)).shr(5)


def test_acc_shifts_fewest_over_every_choice():
    """The program's three shifts: no other three (brute force over a small range) do its shifts
    in fewer ops; the program's own shifts are the ones it asked for, each of them exact."""
    amounts = {3: 6, 4: 4, 6: 5, 9: 2, 13: 1}
    chosen = seq_shifts.acc_shifts_for(amounts)

    def cost(sizes):
        ops = [seq_shifts.shift_ops(n, sizes) for n in amounts]
        return None if None in ops else sum(t * len(o) for t, o in zip(amounts.values(), ops))
    costs = [c for sizes in itertools.combinations(range(1, 14), 3) if (c := cost(sizes)) is not None]
    assert cost(chosen) == min(costs) < cost((1, 4, 16))
    prog = ik_program(_k("q32w"), wide_product=True)
    assert prog.acc_shifts != (1, 4, 16)
    shifts = [i for i in prog.code if i.alu in seq_isa.SHIFTS]
    assert {i.alu for i in shifts} <= set(seq_isa.SHIFTS)


@pytest.mark.parametrize("cfg", ("q18", "q32w"))
def test_rotation_of_a_constant_vector_is_gained_before_its_quadrant_step(cfg):
    """The IK's rotations of constant vectors: their gain products are constants, loaded instead
    of computed; where the rounding of a coordinate times 1/K is a tie (not odd), the quarter
    turn's coordinate is loaded again after the turn, under its condition."""
    a, Const = seq_asm.Asm(_k(cfg)), seq_isa.Const
    ki = a.ki
    args = ("angle", "dx", "dy", "temp", 0)
    assert any(i.pick for i in a.rotate("x", "y", *args))
    shift = ki.inv_gain_frac - ki.cfg.guard_bits
    odd, twos = ki.inv_gain, 0
    while odd % 2 == 0:
        odd, twos = odd // 2, twos + 1
    modulus = 1 << (shift - twos)
    tie = (pow(odd, -1, modulus) << (shift - 1 - twos)) % modulus    # tie * 1/K: exactly half an LSB
    assert (tie * ki.inv_gain) % (1 << shift) == 1 << (shift - 1)
    one = 1 << (ki.cfg.width - 2)
    for x, y, fixes in ((one, 0, 0), (tie, 0, 1), (one, tie, 1), (tie, tie, 2)):
        code = a.rotate(Const(x), Const(y), *args)
        assert not any(i.pick for i in code)
        again = [i for i in code if i.cop in (seq_isa.K_LDX, seq_isa.K_LDY) and i.ca == seq_isa.C_F]
        assert len(again) == fixes
        quadrants = a.gained_quadrants(Const(x), Const(y))
        assert (quadrants["up_x"] is None) == (y != tie) and (quadrants["down_y"] is None) == (x != tie)


def test_register_occupancy_lets_a_load_share_the_last_read():
    """The scheduler's claims on the accumulator: a read at clock t needs the value held during
    t, a write takes clock t + 1 (one past the code for a write in the last clock), so a block
    starting with a load fits in the clock of another block's last read (its store) and not one
    clock earlier; a block reading the accumulator at its first clock never does."""
    from ik5r.hdl.sequenced import schedule
    from ik5r.hdl.sequenced.isa import AluOp, Const, Ins, Var

    store = schedule.Block([Ins(alu=AluOp.LD, rd=Const(1)), Ins(alu=AluOp.ADD, rd=Const(2)),
                            Ins(wr=1, wa=Var("a"))])
    load = schedule.Block([Ins(alu=AluOp.LD, rd=Const(3)), Ins(wr=1, wa=Var("b"))])
    reader = schedule.Block([Ins(alu=AluOp.SHRA), Ins(wr=1, wa=Var("c"))])
    assert ["acc" in keys for keys in store.claims] == [False, True, True]
    table = schedule.Table()
    table.place(store, 0)
    assert table.fits(load, 2) and not table.fits(load, 1)
    assert not table.fits(reader, 2) and table.fits(reader, 3)
    last_write = schedule.Block([Ins(alu=AluOp.LD, rd=Const(1))])
    assert len(last_write.claims) == 2 and last_write.claims[1] == {"acc"}
    table.place(last_write, 3)
    assert len(table) == 4 and not table.fits(reader, 4)


@pytest.mark.parametrize("cfg", ("q32w",))       # internal guard bits: two formats, two saturations
def test_clip_to_a_format_range_is_one_saturation(cfg):
    """A clip whose bounds are those of the internal (or word) format is one SATI (SATW) with no
    status bit, not two compares and two loads; a clip to other bounds keeps them."""
    from ik5r.hdl.graph.trace import trace
    from ik5r.hdl.sequenced.asm import Asm
    from ik5r.hdl.sequenced.isa import AluOp
    from ik5r.hdl.sequenced.lower import Lower

    k = _k(cfg)
    asm = Asm(k)
    top = (1 << (k.internal.cfg.width - 1)) - 1
    assert asm.clip(-top - 1, top) == asm.clip(None, top) == [seq_isa.Ins(alu=AluOp.SATI)]
    word = (1 << (k.cfg.width - 1)) - 1
    if word != top:         # q18: no internal guard bits, the two formats are one
        assert asm.saturating(-word - 1, None) == AluOp.SATW
        assert asm.saturating(-top - 1, word) is None
    assert asm.saturating(0, top) is None and asm.saturating(None, None) is None
    assert [ins.alu for ins in asm.clip(0, top)] == [AluOp.CMPGT, AluOp.LD, AluOp.CMPLT, AluOp.LD]
    lower = Lower(asm, *trace(k)[:2])
    silent = [ins for code in lower.blocks for ins in code if ins.alu == AluOp.SATI and not ins.stat]
    assert silent       # the traced IK has such clips (the wrist's position sums)


def test_adder_sources_checked():
    """The adder takes only ``seq_isa.ADDER_SOURCES`` (its own operand select, off the B bus):
    the interpreter refuses an adding operation on another source (the engine refuses the
    program), and every shipped program keeps to them."""
    prog = ik_program(_k("q18"))
    for cfg in ("q18", "q24", "q32", "q32w"):
        code = ik_program(_k(cfg)).code
        assert all((ins.bsel or seq_isa.BusSource.MEM) in seq_isa.ADDER_SOURCES for ins in code
                   if ins.alu in seq_isa.ADDING)
    bad = seq_isa.Ins(alu=seq_isa.AluOp.ADD, bsel=seq_isa.BusSource.CX)
    prog.code = [bad] + prog.code[1:]
    with pytest.raises(ValueError, match="adding ALU operation"):
        machine.run(prog, [0] * (len(INPUT_WORDS) + 1))


def test_an_atan2_frees_the_cordic_before_rounding_its_angle():
    """An atan2 block reads the CORDIC (z, the zero-vector latch) right after its last
    micro-rotation and rounds the angle after: the CORDIC is free for the next block sooner."""
    from ik5r.hdl.graph.trace import trace
    from ik5r.hdl.sequenced.lower import Lower

    k = _k("q32w")
    joints, events, _ = trace(k)
    blocks = Lower(seq_asm.Asm(k), joints, events).blocks
    atan2s = [code for code in blocks if any(ins.cop == seq_isa.CordicOp.VEC for ins in code)]
    assert len(atan2s) >= 4
    for code in atan2s:
        last_turn = max(t for t, ins in enumerate(code) if ins.cop == seq_isa.CordicOp.VEC)
        reads = [t for t, ins in enumerate(code) if seq_isa.CondSource.ZERO in (ins.ca, ins.cb)
                 or ins.bsel == seq_isa.BusSource.CZ]
        first_round = next(t for t, ins in enumerate(code) if t > last_turn and ins.alu == seq_isa.AluOp.ADD)
        assert max(reads) < first_round, (last_turn, reads, first_round)


def test_no_memory_word_is_read_in_the_clock_it_is_written():
    """The engine's data memory has no collision logic (no_rw_check): no shipped program writes a
    word in the clock the instruction READ_AHEAD later reads it, across the program's end too;
    the check finds a constructed clash, and the engine refuses a program with one."""
    for cfg in ("q18", "q24", "q32", "q32w"):
        for wide in (False, True):
            assert seq_isa.read_write_clash(ik_program(_k(cfg), wide_product=wide).code) is None
    prog = ik_program(_k("q18"))
    writer = next(i for i, ins in enumerate(prog.code) if ins.wr)
    reader = (writer + seq_isa.READ_AHEAD) % len(prog.code)
    code = list(prog.code)
    code[reader] = dataclasses.replace(code[reader], rd=code[writer].wa)
    assert seq_isa.read_write_clash(code) == writer
    last, first_reader = len(code) - 1, seq_isa.READ_AHEAD - 1     # the next pose's
    wrapped = list(prog.code)
    wrapped[last] = dataclasses.replace(wrapped[last], wr=1, wa=prog.code[writer].wa)
    wrapped[first_reader] = dataclasses.replace(wrapped[first_reader], rd=prog.code[writer].wa)
    assert seq_isa.read_write_clash(wrapped) == last


@pytest.mark.filterwarnings("ignore:.*created but never used")
def test_engine_refuses_a_program_with_a_read_write_clash(monkeypatch):
    from ik5r.hdl.sequenced import engine as seq_engine

    prog = ik_program(_k("q18"))
    writer = next(i for i, ins in enumerate(prog.code) if ins.wr)
    reader = (writer + seq_isa.READ_AHEAD) % len(prog.code)
    prog.code[reader] = dataclasses.replace(prog.code[reader], rd=prog.code[writer].wa)
    monkeypatch.setattr(seq_engine, "ik_program", lambda constants, wide_product, poses: prog)
    with pytest.raises(ValueError, match=f"instruction {writer} writes the memory word"):
        seq_engine.SeqEngine(constants=_k("q18"))
    gc.collect()    # the refused engine warns (never elaborated) here, not in a later test


#: Amaranth's simulator takes 15-25 CPU s a case: the default run takes the wide product step at q18
#: (the default core's Verilog is simulated by cocotb, tests/test_cocotb_core.py); the other cases in
#: the slow set.
FULL_RATE_DEFAULT = {("q18", True)}


@pytest.mark.parametrize("cfg, wide", [
    pytest.param(cfg, wide, marks=() if (cfg, wide) in FULL_RATE_DEFAULT else (pytest.mark.slow,))
    for cfg, wide in (("q18", False), ("q32", False), ("q32w", False), ("q18", True), ("q32w", True))])
def test_core_full_rate_and_stalls(cfg, wide):
    k = _k(cfg)
    step = {"q18": 24, "q32": 40, "q32w": 24}[cfg]
    poses = concat(directed_poses(k)[::step], random_poses(k, 1, seed=2)[:2])
    items = inputs_of(poses, TAG_WIDTH)
    expected = with_tags(items, expected_of(k, poses))
    dut = SequencedIKCore(constants=k, tag_width=TAG_WIDTH, wide_product=wide)
    assert dut.options == ({"wide_product": True} if wide else {})
    outputs, accepted, produced = run_stream(dut, items)
    compare(items, expected, outputs)
    # Into an idle core: exactly `latency`; then one pose per program length.
    assert accepted[0] == 2                              # the engine boots in two clocks
    assert produced[0] - accepted[0] == dut.latency
    assert all(b - a == dut.cycles_per_result for a, b in zip(produced, produced[1:]))
    sub = slice(0, 4)
    outputs, _, _ = run_stream(dut, items[sub], stall_seed=9, long_stall=True)
    compare(items[sub], expected[sub], outputs)


@pytest.mark.parametrize("cfg", ["q18", pytest.param("q32w", marks=pytest.mark.slow)])
def test_two_pose_core_full_rate_and_stalls(cfg):
    """``poses=2``: two poses a program at full rate (the first into an idle core after
    ``latency``; two results every program length), and with random input gaps and output
    back-pressure, where the second pose of a program is skipped whenever none is there. At q18
    its program on the interpreter first (one compile of the program for both)."""
    k = _k(cfg)
    if cfg == "q18":
        _two_pose_program_on_interpreter(k)
    poses = concat(directed_poses(k)[::24], random_poses(k, 1, seed=3)[:3])
    items = inputs_of(poses, TAG_WIDTH)
    expected = with_tags(items, expected_of(k, poses))
    dut = SequencedIKCore(constants=k, tag_width=TAG_WIDTH, poses=2)
    run_length = len(ik_program(k, poses=2).code)
    assert dut.options == {"poses": 2} and dut.cycles_per_result == run_length / 2
    outputs, accepted, produced = run_stream(dut, items)
    compare(items, expected, outputs)
    assert produced[0] - accepted[0] == dut.latency
    assert all(b - a == run_length for a, b in zip(produced, produced[2:]))
    outputs, _, _ = run_stream(dut, items[:9], stall_seed=4, long_stall=True)
    compare(items[:9], expected[:9], outputs)
    # One pose alone: the program's second pose is skipped, the first's result comes.
    outputs, accepted, produced = run_stream(dut, items[:1])
    compare(items[:1], expected[:1], outputs)
    assert produced[0] - accepted[0] == dut.latency
    # The output held from the start: three poses in the core (the first's result, the second
    # in the engine, stopped at its first output word, the third in the input register); one
    # fewer than its capacity, which needs a result still held when the next program starts.
    outputs, accepted, produced = run_stream(dut, items[:6], hold_output=5 * dut.latency)
    compare(items[:6], expected[:6], outputs)
    assert sum(a < 5 * dut.latency for a in accepted) == 3 == dut.capacity - 1


def test_core_output_held():
    """The output held long after the core is full: three poses taken (input register, engine,
    output register), none lost, duplicated or reordered; the rest flows once released."""
    k = _k("q18")
    poses = random_poses(k, 1, seed=5)[:5]
    items = inputs_of(poses, TAG_WIDTH)
    expected = with_tags(items, expected_of(k, poses))
    dut = SequencedIKCore(constants=k, tag_width=TAG_WIDTH)
    hold = 5 * dut.latency
    outputs, accepted, produced = run_stream(dut, items, hold_output=hold)
    compare(items, expected, outputs)
    assert sum(a < hold for a in accepted) == dut.capacity
    assert produced[0] == hold


@pytest.mark.parametrize("stalls", (False, True))
def test_serial_wrapper(stalls):
    k = _k("q18")
    poses = concat(directed_poses(k)[::20], random_poses(k, 1, seed=7)[:2])
    expected = ik_outputs(k, poses, model.solve_batch)
    fields = poses.fields()
    dut = SerialIK(constants=k, tag_width=4, beat_bits=8)
    eng, b = dut._engine, dut.beat_bits
    beats = []
    for i in range(len(poses)):
        for word in _engine_words(fields, i, i % 16):
            word &= (1 << eng.in_bits) - 1
            beats += [(word >> (b * j)) & ((1 << b) - 1) for j in range(dut.in_beats)]
    received = []
    last_cycle = []

    async def bench(ctx):
        rng = random.Random(3)
        index = cycle = 0
        while len(received) < len(poses) * 6 * dut.out_beats:
            assert cycle < 2 * dut.cycles_per_result * (len(poses) + 2), "timeout"
            offer = index < len(beats) and (not stalls or rng.random() > 0.3)
            take = not stalls or rng.random() > 0.4
            ctx.set(dut.i.valid, offer)
            if offer:
                ctx.set(dut.i.payload, beats[index])
            ctx.set(dut.o.ready, take)
            _, _, ready, valid, payload = await ctx.tick().sample(dut.i.ready, dut.o.valid, dut.o.payload)
            index += offer and ready
            if valid and take:
                received.append(payload)
            cycle += 1
        last_cycle.append(cycle)

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    width = k.cfg.width
    for i in range(len(poses)):
        words = [sum(received[(6 * i + w) * dut.out_beats + j] << (b * j) for j in range(dut.out_beats))
                 for w in range(6)]
        got = {f"q{j + 1}": machine.wrap_signed(words[j], width) for j in range(5)}
        got["status"], tag = words[5] & ((1 << STATUS_BITS) - 1), words[5] >> STATUS_BITS
        assert got == {name: int(expected[name][i]) for name in got} and tag == i % 16, f"pose {i}"
    if not stalls:
        # Beats every clock: one pose per cycles_per_result clocks, + the clock after power-up
        # (the first pose waits for its first word's beats too).
        assert last_cycle[0] == len(poses) * dut.cycles_per_result + dut.in_beats


@pytest.mark.filterwarnings("ignore:.*created but never used")
@pytest.mark.parametrize("bad", (1, "yes", None))
def test_wide_product_checked(bad):
    """``wide_product`` is True or False (keyword-only): anything else is refused."""
    k = _k("q18")
    with pytest.raises(ValueError, match="wide_product must be True or False"):
        SequencedIKCore(constants=k, wide_product=bad)
    with pytest.raises(ValueError, match="wide_product must be True or False"):
        SerialIK(constants=k, wide_product=bad)
    with pytest.raises(TypeError):
        SequencedIKCore(k, 0, True)
    gc.collect()    # the refused cores warn (never elaborated) here, not in a later test


def test_wide_limbs():
    """A limb of two 15-bit limbs: 30 unsigned bits, or the signed rest at the top."""
    value = -(3 << 44) + (5 << 30) + (1 << 29) + 7
    assert machine.limb(value, 0, False, 2) == (1 << 29) + 7
    assert machine.limb(value, 1, True, 2) == -(3 << 14) + 5
    assert machine.limb(value, 1, False) == 1 << 14        # 15-bit limbs as before


def test_compact_verilog_structure():
    """The generated compact core: one multiplier, the program in a ROM; the wrapper's ports."""
    k = _k("q32w")
    text, pmap = generate("ik", "compact", k)
    assert len(re.findall(r"[\w)] \* [\w$(]", text)) == 1
    assert pmap["cycles_per_result"] == len(ik_program(k).code)
    serial, smap = generate("ik", "compact", k, serial=16)
    widths = {p["name"]: p["width"] for p in smap["ports"]}
    assert widths["i__payload"] == widths["o__payload"] == 16
    assert sum(widths.values()) <= 39         # the UP5K's SG48 package


@pytest.mark.parametrize("most", range(1, 48))
def test_normalising_shifts_shift_by_the_headroom_up_to_the_most(most):
    """The conditional normalisations of an atan2 (each shift taken if the vector still fits)
    shift by min(headroom, most) for every headroom, as the models' shifts by 8 then by 1 do."""
    from ik5r.hdl.sequenced.asm import normalising_shifts

    sizes = normalising_shifts(most)
    assert sum(sizes) == most and all(size in seq_isa.NORMS.values() for size in sizes)
    for headroom in range(64):
        shifted = 0
        for size in sizes:
            if headroom - shifted >= size:
                shifted += size
        assert shifted == min(headroom, most), (sizes, headroom)
