"""Modulo schedules of the compact core's two-pose programs (``hdl/sequenced/modulo.py``): a kept
template is of a design point this checkout compiles and gives a cyclic program of two periods;
that program is bit-exact on the interpreter run after run, with poses skipped where none is
there; the cyclic code refuses a clash and the word sharing respects lifetimes across the program's
end; the constraint solver's template is valid. (The engine running a cyclic program:
``tests/test_seq_core.py``, the two-pose core's test at q18.)"""

from __future__ import annotations

import json

import pytest

from test_ik_core import expected_of, inputs_of, with_tags
from test_seq_core import TAG_WIDTH, _engine_words

from ik5r.core.arm import load_arm
from ik5r.core.fxconfig import constants, load_config
from ik5r.firmware_model import model
from ik5r.firmware_model.poses import concat
from ik5r.firmware_model.vectors import directed_poses, random_poses
from ik5r.hdl.sequenced import cpsat, hints, machine, modulo, program, search
from ik5r.hdl.sequenced.isa import Ins, MulLoad, Var
from ik5r.hdl.sequenced.engine import SequencedIKCore
from ik5r.hdl.sequenced.schedule import blocks_of, climbed, placed
from ik5r.tools.testbench.amaranth_stream import compare, run_stream
from ik5r.tools.testbench.blocks import ik_outputs


def _kept():
    return [(path, json.loads(path.read_text())) for path in sorted(hints.SCHEDULES.glob("modulo/*.json"))]


@pytest.mark.parametrize("path, data", _kept(), ids=lambda v: getattr(v, "stem", ""))
def test_kept_template_is_current_and_shorter(path, data):
    """A kept template is of the blocks of a design point's two-pose program (else
    ``python -m ik5r.hdl.sequenced.search --modulo SECONDS`` again), shorter than the straight
    program, and its compile the cyclic program of two periods."""
    k = constants(load_config(data["config"]), load_arm(data["arm"]))
    _, codes, after = program.program_blocks(k, data["wide_product"], 2)
    assert hints.fingerprint(blocks_of(codes, after)) == path.stem
    assert hints.modulo_hint(blocks_of(codes, after)) == (data["period"], data["starts"])
    assert data["cp_sat_bound"] <= data["period"] and 2 * data["period"] < data["straight_clocks"]
    prog = program.ik_program(k, wide_product=data["wide_product"], poses=2)
    assert prog.cyclic and len(prog.code) == 2 * data["period"]


def _stream(k, prog, count: int):
    poses = concat(directed_poses(k)[::7], random_poses(k, 4, seed=21))
    expected = ik_outputs(k, poses, model.solve_batch)
    fields = poses.fields()
    outs = machine.run_stream(prog, [_engine_words(fields, j, j % 64) for j in range(count)])
    assert len(outs) == count
    for j, out in enumerate(outs):
        assert [out[n] for n in range(5)] + [out["status"], out["tag"]] == \
            [int(expected[f"q{n + 1}"][j]) for n in range(5)] + [int(expected["status"][j]), j % 64], j


@pytest.mark.parametrize("count", [1, 2, 7])
def test_cyclic_program_on_interpreter(cyclic_q18, count):
    """A cyclic program, one pose, two, seven (the last with its partner skipped): every pose's
    words and registers its own across runs, the outputs in order."""
    prog = program.ik_program(cyclic_q18, poses=2)
    assert prog.cyclic
    _stream(cyclic_q18, prog, count)


@pytest.mark.parametrize("path, data", _kept(), ids=lambda v: getattr(v, "stem", ""))
def test_kept_template_program_on_interpreter(path, data):
    k = constants(load_config(data["config"]), load_arm(data["arm"]))
    _stream(k, program.ik_program(k, wide_product=data["wide_product"], poses=2), 7)


def test_the_cyclic_code_refuses_a_clash(cyclic_q18):
    """Both poses' inputs in the same clocks: the word port claimed twice."""
    _, codes, after = program.program_blocks(cyclic_q18, False, 2)
    period, starts = hints.modulo_hint(blocks_of(codes, after))
    both = modulo.two_pose_starts(starts, period)
    modulo.cyclic_code(codes, after, both, 2 * period, 2)
    with pytest.raises(ValueError, match="claimed twice"):
        modulo.cyclic_code(codes, after, [both[0], both[0]] + both[2:], 2 * period, 2)


def test_words_shared_on_the_circle():
    """Lifetimes on the circle of a 10-clock program: ``a`` stored at 8 and read at 1 of the next
    run lives across the end; ``b`` (3 .. 5) may take its word, ``d`` (9 .. 9) may not."""
    a, b, d = [(8, "a", "wr"), (11, "a", "rd")], [(3, "b", "wr"), (5, "b", "rd")], [(9, "d", "wr"), (9, "d", "rd")]
    words = _words(10, a + b + d)
    assert words["a"] == words["b"] != words["d"]


def _words(clocks: int, values) -> dict:
    """{value: word} of :func:`modulo.share_words` for one-instruction blocks (clock, value,
    store or read)."""
    blocks_starts = [([Ins(wr=1, wa=Var(name)) if kind == "wr" else Ins(mld=MulLoad.A, rd=Var(name))], t)
                     for t, name, kind in values]
    placed = [Ins() for _ in range(clocks)]
    for (ins,), t in blocks_starts:
        placed[t % clocks] = placed[t % clocks].merge(ins)
    names = {}
    for before, after in zip(placed, modulo.share_words(placed, blocks_starts)):
        for ref, word in ((before.wa, after.wa), (before.rd, after.rd)):
            if isinstance(ref, Var):
                names[ref.name] = word.name
    return names


@pytest.fixture(scope="module")
def q18_cyclic(tmp_path_factory):
    """A few seconds of CP-SAT from q18's one-pose placement: (its template, kept in a schedules
    directory of its own, the climb's length, the solver's result)."""
    k = constants(load_config("q18"))
    _, one, _ = program.program_blocks(k, False, 1)
    template = blocks_of(one)
    table, _ = climbed(template)
    found = cpsat.solve(template, hint=search._starts(table, template), seconds=3, workers=1, modulo=True)
    schedules = tmp_path_factory.mktemp("schedules")
    _, codes, after = program.program_blocks(k, False, 2)
    (schedules / "modulo").mkdir()
    (schedules / "modulo" / f"{hints.fingerprint(blocks_of(codes, after))}.json").write_text(
        json.dumps({"period": found.clocks, "starts": found.starts}))
    return k, schedules, len(table), found


@pytest.fixture
def cyclic_q18(q18_cyclic, monkeypatch):
    """q18's two-pose program compiled as the cyclic program of that template (the compile's
    cache cleared before and after)."""
    k, schedules, _, _ = q18_cyclic
    monkeypatch.setattr(hints, "SCHEDULES", schedules)
    program._compile.cache_clear()
    yield k
    program._compile.cache_clear()


def test_the_constraint_solvers_template_is_valid(q18_cyclic, cyclic_q18):
    """The template's period at most the one-pose placement's it started from, its bound below;
    folded into a cyclic program without a clash; bit-exact."""
    k, _, straight, found = q18_cyclic
    assert found.bound <= found.clocks <= straight
    prog = program.ik_program(k, poses=2)
    assert prog.cyclic and len(prog.code) == 2 * found.clocks
    _stream(k, prog, 3)


def test_cyclic_core_full_rate_and_stalls(cyclic_q18):
    """The engine on a cyclic program: two results a program length at full rate; one pose
    alone comes out after ``latency`` (the engine runs on through the skipped poses while it is
    in flight, then waits); random input gaps and output back-pressure lose, duplicate or
    reorder nothing; the output held, the core full."""
    k = cyclic_q18
    poses = concat(directed_poses(k)[::24], random_poses(k, 1, seed=3)[:3])
    items = inputs_of(poses, TAG_WIDTH)
    expected = with_tags(items, expected_of(k, poses))
    dut = SequencedIKCore(constants=k, tag_width=TAG_WIDTH, poses=2)
    run_length = len(program.ik_program(k, poses=2).code)
    outputs, accepted, produced = run_stream(dut, items)
    compare(items, expected, outputs)
    assert produced[0] - accepted[0] == dut.latency > run_length // 2
    assert all(b - a == run_length for a, b in zip(produced, produced[2:]))
    for count in (1, 2):
        outputs, accepted, produced = run_stream(dut, items[:count])
        compare(items[:count], expected[:count], outputs)
        assert produced[0] - accepted[0] == dut.latency
    outputs, _, _ = run_stream(dut, items[:9], stall_seed=4, long_stall=True)
    compare(items[:9], expected[:9], outputs)
    outputs, accepted, produced = run_stream(dut, items[:6], hold_output=5 * dut.latency)
    compare(items[:6], expected[:6], outputs)
    # Held from the start: the core fills to its capacity (the first result in the output
    # register, the second stopped at its first output word, the third in the engine, the fourth
    # in the input register), which a straight program reaches only with a result still held
    # when the next run starts.
    assert sum(a < 5 * dut.latency for a in accepted) == dut.capacity


def test_the_search_keeps_a_template_only_if_shorter(tmp_path, monkeypatch, capsys):
    """``--modulo``: a few seconds of CP-SAT on q18's template; kept (and then compiled to the
    cyclic program) exactly when its two periods are shorter than the straight two-pose
    program; the period and the bound reported either way."""
    k = constants(load_config("q18"))
    _, codes, after = program.program_blocks(k, False, 2)
    blocks = blocks_of(codes, after)
    straight = len(placed(blocks, *hints.hint(blocks)))        # q18's kept orders, no climb
    for kept in hints.order_files():
        (tmp_path / kept.name).write_text(kept.read_text())
    monkeypatch.setattr(hints, "SCHEDULES", tmp_path)
    path, found = search.modulo_point({"config": "q18", "arm": None, "wide_product": False, "seed": 1}, 3)
    assert (path is None) == (2 * found.clocks >= straight) and found.bound <= found.clocks
    assert hints.modulo_hint(blocks) == (None if path is None else (found.clocks, found.starts))
    assert search.main(["--config", "q18", "--modulo", "1"]) == 0
    assert f"CP-SAT's bound" in capsys.readouterr().out
