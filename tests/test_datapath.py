"""The typed stages of ``ik5r.hdl.datapath.stages`` and its construction-time check."""

import gc

import pytest
from amaranth.hdl import Signal, signed

from ik5r.core.fxconfig import constants, load_config
from ik5r.hdl.blocks.acos import Acos
from ik5r.hdl.blocks.cordic import Rotate
from ik5r.hdl.datapath.adders import Ecp5Adders, adders_for
from ik5r.hdl.datapath.stages import Datapath, Stage, StageKind
from ik5r.hdl.datapath.expr import drop
from ik5r.hdl.blocks.stream_block import StreamBlock


def _inputs():
    return {"x": Signal(signed(8), name="x"), "y": Signal(signed(8), name="y")}


def test_a_wrong_key_is_named_with_its_stage():
    dp = Datapath("demo")
    dp.add("sum", lambda s: dict(drop(s, "x", "y"), total=s["x"] + s["y"]))
    dp.add("twice", lambda s: dict(drop(s, "totl"), double=s["totl"] * 2))
    with pytest.raises(ValueError, match=r"demo: stage 'twice' reads 'totl', which no earlier stage produces"):
        dp.check(_inputs(), lambda s: {"double": s["double"]})


def test_a_value_never_read_is_named_with_its_producer():
    dp = Datapath("demo")
    dp.add("sum", lambda s: dict(drop(s, "x", "y"), total=s["x"] + s["y"], spare=s["x"]))
    dp.add("twice", lambda s: dict(drop(s, "total", "spare"), double=s["total"] * 2))
    with pytest.raises(ValueError, match=r"demo: 'spare' produced by stage 'sum' is never read "
                                         r"\(stage 'twice' drops or replaces it\)"):
        dp.check(_inputs(), lambda s: {"double": s["double"]})
    ok = Datapath("demo")
    ok.add("sum", lambda s: dict(drop(s, "x", "y"), total=s["x"] + s["y"], spare=s["x"]))
    with pytest.raises(ValueError, match=r"'spare' produced by stage 'sum' is never read \(not an output\)"):
        ok.check(_inputs(), lambda s: {"total": s["total"]})
    ok.check(_inputs(), lambda s: {"total": s["total"], "spare": s["spare"]})


def test_the_outputs_must_exist():
    dp = Datapath("demo")
    dp.add("sum", lambda s: dict(drop(s, "x", "y"), total=s["x"] + s["y"]))
    with pytest.raises(ValueError, match=r"the outputs read 'totl'"):
        dp.check(_inputs(), lambda s: {"total": s["totl"]})


@pytest.mark.filterwarnings("ignore::amaranth.hdl.UnusedElaboratable")
def test_a_block_with_a_wrong_key_fails_at_construction():
    class Broken(StreamBlock):
        def __init__(self, k):
            dp = Datapath("broken")
            dp.add("negate", lambda s: dict(drop(s, "x"), y=-s["xx"]))
            word = signed(k.cfg.width)
            super().__init__(constants=k, arch="pipelined", tag_width=0,
                             in_fields={"x": (word, None, "x")}, out_fields={"y": (word, None, "y")},
                             datapath=dp)

        def _inputs(self, payload):
            return {"x": payload.x}

        def _outputs(self, state):
            return {"y": state["y"]}

    with pytest.raises(ValueError, match=r"broken: stage 'negate' reads 'xx'"):
        Broken(constants(load_config("q18")))
    gc.collect()   # the half-built component warns (UnusedElaboratable) here, not in a later test


def test_stage_kinds():
    fn = lambda s: s  # noqa: E731
    assert Stage.of(("w", fn, 0, False)).kind is StageKind.WIRING
    assert Stage.of(("r", fn, 1, False)).kind is StageKind.REGISTERED
    stage = Stage.of(("i", fn, 5, True))
    assert stage.kind is StageKind.ITERATED and stage.count == 5 and tuple(stage) == ("i", fn, 5, True)
    with pytest.raises(ValueError, match="a wiring stage has count 0"):
        Stage("w", StageKind.WIRING, fn, 1)
    with pytest.raises(ValueError, match="count must be at least 1"):
        Stage("i", StageKind.ITERATED, fn, 0)
    dp = Datapath("demo")
    dp.add("a", fn)
    dp.add_wiring(fn)
    dp.add_iter("b", lambda s, i: s, 3)
    assert [s.kind for s in dp.stages] == [StageKind.REGISTERED, StageKind.WIRING, StageKind.ITERATED]
    assert dp.latency == 4


def test_blocks_expose_their_chains_by_split_point():
    k = constants(load_config("q18"))
    rot = Rotate.chain(k, skewed=True)
    tail = rot.part("micro_rotations")
    assert [s.name for s in tail.stages] == ["ro_it", "ro_unguard", "ro_clip"]
    acos = Acos.chain(k)
    assert acos.part("factors", "radicand").stages[0].name == "ac_factors"
    assert acos.part("atan2").stages[0].name == "at_coarse"
    assert acos.part("factors", "atan2").latency + acos.part(None, "factors").latency \
        + acos.part("atan2").latency == acos.latency
    with pytest.raises(KeyError, match="no split point 'gain'"):
        rot.part("gain")


def test_the_adder_mapping_is_explicit():
    assert adders_for("generic").dsp == "generic"
    adders = adders_for("ecp5")
    assert isinstance(adders, Ecp5Adders)
    a, b, s = Signal(signed(6)), Signal(signed(6)), Signal()
    adders.add_sub(a, b, s)
    assert len(adders.take()) == 1 and adders.take() == []


def test_the_chains_declare_what_they_read_and_leave():
    """Each chain, checked alone from its declared inputs to its declared outputs."""
    from ik5r.hdl.blocks.chains import namespaced
    from ik5r.hdl.blocks.cordic import add_atan2
    from ik5r.hdl.pipelined.const_rotate import rotate_const_chain
    k = constants(load_config("q18"))
    word = signed(k.cfg.width)
    for skewed in (True, False):
        Rotate.chain(k, skewed=skewed).check_chain(word)
        namespaced(rotate_const_chain(k, (k.one_u, 0), skewed=skewed, adders=adders_for("generic")),
                   "C1__").check_chain(word)
    Acos.chain(k).check_chain(word)
    atan2 = Datapath("atan2", inputs=("y", "x"), outputs=("angle", "zero"))
    add_atan2(atan2, k, y="y", x="x", magnitude=False, zero=True)
    namespaced(atan2, "T1__").check_chain(word)
    chain = namespaced(Acos.chain(k), "EL__")
    assert chain.inputs == ("EL__x",) and chain.outputs == ("EL__angle", "EL__sine", "EL__saturated")
    chain.check_chain(word)
    wrong = Acos.chain(k)
    wrong.outputs = ("angle", "cosine")
    with pytest.raises(ValueError, match="the outputs read 'cosine'"):
        wrong.check_chain(word)


def test_onehot_select_is_select():
    """``onehot_select`` (the compact core's product register) gives ``select``'s value for
    every index: each option, sign-extended, and 0 past the end of the options."""
    from amaranth.hdl import Const, Module, Signal, signed
    from amaranth.sim import Simulator

    from ik5r.hdl.datapath.expr import onehot_select, select

    index = Signal(3)
    product = Const(-5, signed(5))
    options = [product.shift_left(s) for s in (0, 3, 6, 9, 12)]
    m = Module()
    got, want = Signal(signed(20)), Signal(signed(20))
    m.d.comb += [got.eq(onehot_select(options, index)), want.eq(select(options, index))]
    seen = []

    async def bench(ctx):
        for i in range(8):
            ctx.set(index, i)
            seen.append((ctx.get(got), ctx.get(want)))

    sim = Simulator(m)
    sim.add_testbench(bench)
    sim.run()
    assert seen == [(-5 << s, -5 << s) for s in (0, 3, 6, 9, 12)] + [(0, 0)] * 3
