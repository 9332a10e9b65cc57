"""Kept block orders of the compact core's programs (``hdl/sequenced/hints.py``, found by the
offline search of ``hdl/sequenced/search.py``): every kept order is of a design point this
checkout compiles, gives the program length it was kept for, and that program is bit-exact; a
compile uses a kept order, and without one climbs as before; the search is deterministic."""

from __future__ import annotations

import json

import numpy as np
import pytest

from test_seq_core import _engine_words

from ik5r.core.arm import load_arm
from ik5r.core.fxconfig import constants, load_config
from ik5r.firmware_model import model
from ik5r.firmware_model.poses import concat
from ik5r.firmware_model.vectors import directed_poses, random_poses
from ik5r.hdl.sequenced import cpsat, hints, machine, program, search
from ik5r.hdl.sequenced.schedule import blocks_of, climbed, placed
from ik5r.tools.testbench.blocks import ik_outputs


def _kept():
    return [(path, json.loads(path.read_text())) for path in hints.order_files()]


def _design_point(data):
    k = constants(load_config(data["config"]), load_arm(data["arm"]))
    return k, program.program_blocks(k, data["wide_product"], data["poses"])


def test_a_kept_order_is_of_the_q32w_two_pose_program():
    assert any(d["config"] == "q32w" and d["poses"] == 2 and not d["wide_product"] for _, d in _kept())


@pytest.mark.parametrize("path, data", _kept(), ids=lambda v: getattr(v, "stem", ""))
def test_kept_order_is_current_and_shorter(path, data):
    """A kept order whose fingerprint no design point has any more is dead weight (the lowering
    changed): ``python -m ik5r.hdl.sequenced.search --renew`` searches its design point again."""
    k, (_, codes, after) = _design_point(data)
    blocks = blocks_of(codes, after)
    assert hints.fingerprint(blocks) == path.stem, (
        f"{path.name}: no design point has these blocks (python -m ik5r.hdl.sequenced.search --renew)")
    assert hints.hint(blocks) == (data["priorities"], data.get("starts"))
    assert search.kept_text(data) == path.read_text()
    assert len(placed(blocks, data["priorities"], data.get("starts"))) == data["clocks"] < data["climb_clocks"]
    assert data.get("cp_sat_bound", 0) <= data["clocks"]
    prog = program.ik_program(k, wide_product=data["wide_product"], poses=data["poses"])
    # A modulo schedule of the same blocks, if kept, is what the compile takes (shorter).
    cyclic = hints.modulo_hint(blocks)
    assert len(prog.code) == (2 * cyclic[0] if cyclic else data["clocks"])


@pytest.mark.parametrize("path, data", _kept(), ids=lambda v: getattr(v, "stem", ""))
def test_kept_order_program_on_interpreter(path, data):
    """The kept order's program on the interpreter, a few runs of directed and random poses
    (the whole directed set: tests/test_seq_core.py, slow set)."""
    k = constants(load_config(data["config"]), load_arm(data["arm"]))
    _bit_exact_on_interpreter(k, program.ik_program(k, wide_product=data["wide_product"], poses=data["poses"]))


def _bit_exact_on_interpreter(k, prog):
    directed = directed_poses(k)
    spread = np.linspace(0, len(directed) - 1, 6 * prog.poses).astype(int)    # every kind of pose
    poses = concat(directed[spread], random_poses(k, 2 * prog.poses, seed=5))
    expected = ik_outputs(k, poses, model.solve_batch)
    fields = poses.fields()
    for first in range(0, len(poses) - prog.poses + 1, prog.poses):
        run = range(first, first + prog.poses)
        outs = machine.run_poses(prog, [_engine_words(fields, j, j % 64) for j in run])
        for j, out in zip(run, outs):
            assert [out[n] for n in range(5)] + [out["status"]] == \
                [int(expected[f"q{n + 1}"][j]) for n in range(5)] + [int(expected["status"][j])], j


def _q18_blocks():
    k = constants(load_config("q18"))
    _, codes, after = program.program_blocks(k)
    return k, codes, after, blocks_of(codes, after)


def test_the_compile_takes_a_kept_order(tmp_path, monkeypatch):
    """A kept order decides the program (here a poor one: every block at the same priority, so
    in list order), and no kept order means the climb."""
    k, codes, after, blocks = _q18_blocks()
    monkeypatch.setattr(hints, "SCHEDULES", tmp_path)
    assert hints.hint(blocks) is None
    climbed_length = len(program._compile.__wrapped__(k).code)
    flat = [0] * len(blocks)
    (tmp_path / f"{hints.fingerprint(blocks)}.json").write_text(json.dumps({"priorities": flat}))
    assert hints.hint(blocks) == (flat, None)
    kept_length = len(program._compile.__wrapped__(k).code)
    assert kept_length == len(placed(blocks, flat)) > climbed_length
    (tmp_path / f"{hints.fingerprint(blocks)}.json").write_text(json.dumps({"priorities": flat[1:]}))
    with pytest.raises(ValueError, match="priorities for"):
        hints.hint(blocks)
    (tmp_path / f"{hints.fingerprint(blocks)}.json").write_text(
        json.dumps({"priorities": flat, "starts": [0] * (len(blocks) - 1)}))
    with pytest.raises(ValueError, match="starts for"):
        hints.hint(blocks)


def test_kept_starts_place_every_block_there(tmp_path, monkeypatch):
    """Starts kept with an order (a constraint solver's placement) give back that placement
    whatever the order, and the compile takes it: here the climb's own placement, kept with
    the reversed order, whose list scheduling alone is longer."""
    k, codes, after, blocks = _q18_blocks()
    table, prio = climbed(blocks)
    starts = search._starts(table, blocks)
    reverse = [-p for p in prio]
    assert len(placed(blocks, reverse)) > len(table)
    again = placed(blocks, reverse, starts)
    assert search._starts(again, blocks) == starts and len(again) == len(table)
    monkeypatch.setattr(hints, "SCHEDULES", tmp_path)
    (tmp_path / f"{hints.fingerprint(blocks)}.json").write_text(json.dumps({"priorities": reverse, "starts": starts}))
    assert len(program._compile.__wrapped__(k).code) == len(table)


@pytest.fixture(scope="module")
def q18_solved():
    """CP-SAT's placement of the q18 program, a few seconds from a poor one (the climb's order
    reversed): (constants, blocks, that poor placement, the solver's)."""
    k, codes, after, blocks = _q18_blocks()
    _, prio = climbed(blocks)
    poor = placed(blocks, [-p for p in prio])
    return k, blocks, poor, cpsat.solve(blocks, hint=search._starts(poor, blocks), seconds=3, workers=1)


def test_the_constraint_solver_places_the_blocks_validly(q18_solved):
    """Every block of CP-SAT's placement at the start the solver gave when list-scheduled no
    earlier than it (so the model's rules are the placer's, or the placer would move a block),
    shorter than its first solution, its lower bound below."""
    k, blocks, poor, found = q18_solved
    assert found.bound <= found.clocks < len(poor)
    order = [found.clocks - s for s in found.starts]
    again = placed(blocks, order, found.starts)
    assert search._starts(again, blocks) == found.starts and len(again) == found.clocks


def test_the_constraint_solvers_program_is_bit_exact(q18_solved, tmp_path, monkeypatch):
    """The compile of a kept CP-SAT placement, on the interpreter."""
    k, blocks, _, found = q18_solved
    monkeypatch.setattr(hints, "SCHEDULES", tmp_path)
    order = [found.clocks - s for s in found.starts]
    (tmp_path / f"{hints.fingerprint(blocks)}.json").write_text(json.dumps({"priorities": order, "starts": found.starts}))
    prog = program._compile.__wrapped__(k)
    assert len(prog.code) == found.clocks
    _bit_exact_on_interpreter(k, prog)


def test_the_fingerprint_is_of_the_blocks():
    _, codes, after, blocks = _q18_blocks()
    assert hints.fingerprint(blocks_of(codes, after)) == hints.fingerprint(blocks)
    assert hints.fingerprint(blocks_of(codes[:1] + codes[2:], after)) != hints.fingerprint(blocks)


def test_search_is_deterministic_and_never_longer():
    _, _, _, blocks = _q18_blocks()
    table, prio = climbed(blocks)
    seen = []
    runs = [search.evolve(blocks, prio, evaluations=1000, seed=3, progress=lambda d, n: seen.append(n))
            for _ in range(2)]
    assert runs[0] == runs[1]
    length, order = runs[0]
    assert length == len(placed(blocks, order)) <= len(table)
    assert seen and seen[-1] == length


def test_renew_searches_a_stale_order_again(tmp_path, monkeypatch):
    """A kept order of blocks no design point has (here a made-up fingerprint) is searched again
    for its design point and replaced; a current one is left alone."""
    monkeypatch.setattr(hints, "SCHEDULES", tmp_path)
    point = {"config": "q18", "arm": None, "poses": 1, "wide_product": False, "evaluations": 50, "seed": 2}
    current = search.search_point(point)
    stale = tmp_path / "0123456789abcdef.json"
    stale.write_text(current.read_text().replace('"evaluations": 50', '"evaluations": 60'))
    before = current.read_text()
    [(old, new)] = search.renew()
    assert old == stale and not stale.exists() and new == current
    renewed = json.loads(new.read_text())
    assert renewed["evaluations"] == 60 and renewed["clocks"] <= renewed["climb_clocks"]
    assert new.read_text() != before and search.renew() == []


def test_a_solver_run_again_starts_from_the_kept_placement(tmp_path, monkeypatch):
    """With the shipped q18 order kept (shorter than the climb), a search with no evaluations
    and a second of CP-SAT keeps a program no longer than it, with its bound."""
    k, codes, after, blocks = _q18_blocks()
    kept = hints.hint(blocks)
    assert kept is not None
    kept_clocks = len(placed(blocks, *kept))
    monkeypatch.setattr(hints, "SCHEDULES", tmp_path)
    (tmp_path / f"{hints.fingerprint(blocks)}.json").write_text(json.dumps({"priorities": kept[0], "starts": kept[1]}))
    point = {"config": "q18", "arm": None, "poses": 1, "wide_product": False, "evaluations": 0, "seed": 1,
             "cp_sat_seconds": 1}
    again = json.loads(search.search_point(point).read_text())
    assert again["cp_sat_bound"] <= again["clocks"] <= kept_clocks < again["climb_clocks"]
    assert len(placed(blocks, again["priorities"], again.get("starts"))) == again["clocks"]
