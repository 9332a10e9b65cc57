"""The stash (``ik5r.hdl.datapath.stash``): values a datapath sets aside for many stages, a
delay element of the datapath's own stage list (no state between builds, no call order)."""

import gc
import random

import pytest
from amaranth.back import rtlil
from amaranth.hdl import Module, Signal, signed

from ik5r.core.fxconfig import constants, load_config
from ik5r.hdl.blocks.stream_block import StreamBlock
from ik5r.hdl.datapath.build import build
from ik5r.hdl.datapath.expr import drop
from ik5r.hdl.datapath.stages import Datapath, StageKind
from ik5r.tools.testbench.amaranth_stream import run_stream

WORD = signed(8)


def _same(s):
    return dict(s)


def _delayed(short: int = 2, long: int = 6) -> Datapath:
    """``x`` set aside for ``short`` register stages (a register chain), ``y`` for ``long`` (a
    RAM ring buffer), while ``d = x - y`` goes through every register."""
    dp = Datapath("demo")
    dp.add("first", lambda s: dict(s, d=s["x"] - s["y"]))
    hx, hy = dp.stash("x"), dp.stash("y")
    for t in range(long):
        if t == short:
            dp.unstash(hx)
        dp.add(f"pad{t}", _same)
    dp.unstash(hy)
    dp.add("last", _same)
    return dp


class Delayed(StreamBlock):
    """Outputs the inputs ``x``, ``y`` that went through the stash and ``d`` that did not."""

    def __init__(self, k, dp, arch="pipelined"):
        fields = {name: (WORD, None, name) for name in ("x", "y")}
        super().__init__(constants=k, arch=arch, tag_width=0, in_fields=fields,
                         out_fields={**fields, "d": (signed(9), None, "d")}, datapath=dp)

    def _inputs(self, payload):
        return {"x": payload.x, "y": payload.y}

    def _outputs(self, state):
        return {"x": state["x"], "y": state["y"], "d": state["d"]}


@pytest.fixture(scope="module")
def k():
    return constants(load_config("q18"))


def test_stashed_values_come_back_with_their_item(k):
    """Each item's x and y, set aside 2 and 6 stages, meet its own d again: at full rate and
    with random input gaps and output back-pressure (a wrong delay pairs another item's)."""
    rng = random.Random(5)
    items = [{"x": rng.randrange(-128, 128), "y": rng.randrange(-128, 128)} for _ in range(40)]
    expected = [dict(item, d=item["x"] - item["y"]) for item in items]
    dut = Delayed(k, _delayed())
    assert dut._dp.stash_spans() == [(1, 3, ("x",)), (1, 7, ("y",))]
    for options in ({}, {"stall_seed": 3}):
        outputs, _, _ = run_stream(dut, items, **options)
        assert outputs == expected


def test_short_waits_are_registers_long_ones_a_ram(k):
    text = rtlil.convert(Delayed(k, _delayed()))
    assert "stash_1_3_d1" in text and "stash_1_3_d2" not in text
    assert "stash_1_7_wptr" in text and "stash_1_7_q" in text and "stash_1_3_q" not in text


def test_no_state_between_builds(k):
    """Elaborated twice (as the construction check, a simulation and the Verilog each walk the
    stages), the same design: nothing to reset, no order to call things in."""
    dut = Delayed(k, _delayed())
    assert rtlil.convert(dut) == rtlil.convert(dut)


def test_the_stash_stages_are_pure():
    dp = _delayed()
    put = next(stage for stage in dp.stages if stage.kind is StageKind.STASH)
    state = {"x": Signal(WORD), "y": Signal(WORD), "d": Signal(signed(9))}
    assert put.fn(state) == {"y": state["y"], "d": state["d"]} and "x" in state
    back = next(stage for stage in dp.stages if stage.kind is StageKind.UNSTASH)
    assert back.fn({"d": state["d"]}, {"x": state["x"]}) == {"d": state["d"], "x": state["x"]}


def _inputs():
    return {"x": Signal(WORD, name="x"), "y": Signal(WORD, name="y")}


def _outputs(s):
    return {key: s[key] for key in ("x", "y", "d")}


def test_mistakes_are_named_when_the_datapath_is_made():
    dp = Datapath("demo")
    handle = dp.stash("x")
    with pytest.raises(ValueError, match="'z' was not stashed here"):
        dp.unstash(handle, "z")
    dp.add("pad", _same)
    dp.unstash(handle)
    with pytest.raises(ValueError, match="'x' taken twice"):
        dp.unstash(handle, "x")
    never = _delayed()
    never.stages = [stage for stage in never.stages if stage.kind is not StageKind.UNSTASH or
                    stage.keys != ("y",)]
    with pytest.raises(ValueError, match=r"stashed but never taken back: \['y'\]"):
        never.check(_inputs(), lambda s: {key: s[key] for key in ("x", "d")})
    at_once = Datapath("demo")
    at_once.add("first", lambda s: dict(s, d=s["x"] - s["y"]))
    at_once.unstash(at_once.stash("x"))
    at_once.add("last", _same)
    with pytest.raises(ValueError, match="'x': zero distance"):
        at_once.check(_inputs(), _outputs)
    away = Datapath("demo")
    away.add("first", lambda s: dict(s, d=s["x"] - s["y"]))
    back = away.stash("x")
    away.add("reads", lambda s: dict(drop(s, "x", "d"), d=s["d"] + s["x"]))
    away.unstash(back)
    away.add("last", _same)
    with pytest.raises(ValueError, match="stage 'reads' reads 'x', which no earlier stage produces"):
        away.check(_inputs(), _outputs)


@pytest.mark.filterwarnings("ignore::amaranth.hdl.UnusedElaboratable")
def test_a_stash_is_a_pipelined_delay_line(k):
    dut = Delayed(k, _delayed(), arch="iterative")
    dut._MustUse__used = True      # its build is what fails: never elaborated
    with pytest.raises(ValueError, match="a stash is a delay line of the pipelined arch"):
        build(dut._dp, Module(), "iterative", dut._state_of(dut.i.payload), dut._payload, dut.i, dut.o)
    gc.collect()   # the unbuilt component warns (UnusedElaboratable) here, not in a later test
