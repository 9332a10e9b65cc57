"""The two elaborations of a :class:`~ik5r.hdl.datapath.stages.Datapath`: pipelined (one register set
per stage and step, an output FIFO and credits) and iterative (one item in flight, iterated
stages fed back). See
:mod:`.datapath` for what each architecture is; both evaluate the same expressions."""

from __future__ import annotations

from amaranth.hdl import Cat, Mux, Signal, Value

from ik5r.core.modes import ARCHS, DSPS, Arch, Dsp

from .output_fifo import CreditFifo
from .stages import Stage
from .products import DspBudget, Product
from .stash import Stashes, build_stash

__all__ = ["build", "build_pipelined", "build_iterative"]


def build(dp, m, arch: str, inputs: dict, payload_of, i, o, dsp: str = Dsp.GENERIC,
          max_dsp: int | None = None) -> None:
    """Elaborate the datapath ``dp`` into ``m`` between the streams ``i`` (its payload already
    turned into the state ``inputs``) and ``o``, whose payload fields ``payload_of(final_state)
    -> {field: value}`` gives. ``dsp`` (one of :data:`DSPS`, the datapath's :attr:`adders`' own)
    and ``max_dsp`` (:class:`DspBudget`) apply to the pipelined architecture."""
    if dsp not in DSPS:
        raise ValueError(f"dsp must be one of {DSPS}, got {dsp!r}")
    if dsp == Dsp.ECP5 and dp.adders.dsp != dsp:
        raise ValueError(f"datapath {dp.name!r}: built with dsp={dsp!r}, made with "
                         f"adders for {dp.adders.dsp!r} (Datapath(adders=adders_for(dsp)))")
    if arch != Arch.PIPELINED and any(getattr(Stage.of(stage).fn, "grouped", False) for stage in dp.stages):
        raise ValueError(f"datapath {dp.name!r}: micro-steps grouped per stage need the pipelined arch")
    if arch != Arch.PIPELINED and dp.stash_spans():
        raise ValueError(f"datapath {dp.name!r}: a stash is a delay line of the pipelined arch")
    if arch == Arch.PIPELINED:
        build_pipelined(dp, m, inputs, payload_of, i, o, dsp, DspBudget(max_dsp))
    elif arch == Arch.ITERATIVE:
        build_iterative(dp, m, inputs, payload_of, i, o)
    else:
        raise ValueError(f"arch must be one of {ARCHS}, got {arch!r}")


def _registers(dp, prefix, values):
    regs = {}
    for key, value in values.items():
        shape = dp.shapes.get(key, Value.cast(value).shape())
        regs[key] = Signal(shape, name=f"{prefix}_{key}", reset_less=True)
    return regs


# --- pipelined ----------------------------------------------------------------------------------

def _credits(dp, m, i, o, depth):
    """The output FIFO and its credits (free slots not yet promised to an item in flight);
    returns (fifo, the input transfer)."""
    credits = Signal(range(depth + 1), init=depth, name=f"{dp.name}_credits")
    # ``credits != 0``, kept in a register of its own: ``i.ready`` is a flip-flop output.
    has_credit = Signal(init=1, name=f"{dp.name}_has_credit")
    fifo = m.submodules[f"{dp.name}_output_fifo"] = CreditFifo(
        width=o.payload.shape().size, depth=depth)
    taken_in = Signal(name=f"{dp.name}_taken_in")
    taken_out = Signal(name=f"{dp.name}_taken_out")
    m.d.comb += [
        i.ready.eq(has_credit),
        taken_in.eq(i.valid & has_credit),
        taken_out.eq(fifo.r_rdy & o.ready),
    ]
    with m.If(taken_in & ~taken_out):
        m.d.sync += [credits.eq(credits - 1), has_credit.eq(credits != 1)]
    with m.Elif(taken_out & ~taken_in):
        m.d.sync += [credits.eq(credits + 1), has_credit.eq(1)]
    return fifo, taken_in


def _pipeline_step(dp, m, stage, step, state, valid, loaded, dsp, budget):
    """One register set of ``stage`` (its ``step``-th for an iterated one); returns (registers,
    valid, what each register is loaded with)."""
    prefix = f"{stage.name}{step}" if stage.iterated else stage.name
    out = stage.fn(state, step) if stage.iterated else stage.fn(state)
    for index, cell in enumerate(dp.adders.take()):
        m.submodules[f"{prefix}_add_sub{index}"] = cell
    regs = _registers(dp, prefix, out)
    stage_valid = Signal(name=f"{prefix}_valid")
    plain, loads = list(regs), dict(out)
    if dsp == Dsp.ECP5:
        for key in regs:
            if not isinstance(out[key], Product):
                continue
            if not budget.wants_dsp(out[key]):
                loads[key] = out[key].lut_value()
            elif out[key].map_ecp5(m, f"{prefix}_{key}", regs[key], loaded):
                plain.remove(key)
    m.d.sync += [regs[key].eq(loads[key]) for key in plain]
    m.d.sync += stage_valid.eq(valid)
    return regs, stage_valid, {id(regs[key]): (regs[key], loads[key]) for key in regs}


def build_pipelined(dp, m, inputs, payload_of, i, o, dsp, budget: DspBudget):
    fifo, taken_in = _credits(dp, m, i, o, dp.capacity(Arch.PIPELINED))
    state, valid = dict(inputs), taken_in
    # What each register of the previous stage is loaded with (for the ECP5 DSP mapping).
    loaded = {}
    # The values an unstash brings back: the outputs of the delay lines made at the end.
    stashes, latency = Stashes(lambda key, value: Signal(value.shape(), name=f"stash_{key}")), 0
    for stage in map(Stage.of, dp.stages):
        if stage.count == 0:
            state = stage.wire(state, stashes, latency)
            continue
        for step in range(stage.count):
            state, valid, loaded = _pipeline_step(dp, m, stage, step, state, valid, loaded, dsp, budget)
        latency += stage.count
    stashes.check_empty()

    payload = Signal(o.payload.shape(), name=f"{dp.name}_result")
    for field, value in payload_of(state).items():
        m.d.comb += getattr(payload, field).eq(value)
    # A register in front of the FIFO, placed next to it: the FIFO's RAMs sit in block RAM
    # rows far from the end of a large pipeline, and the FIFO's level counter, which reads
    # the write enable, got a long route there and back (the IK core's slowest path).
    fifo_data = Signal.like(payload, name=f"{dp.name}_fifo_data", reset_less=True)
    fifo_write = Signal(name=f"{dp.name}_fifo_write")
    m.d.sync += [fifo_data.eq(payload), fifo_write.eq(valid)]
    m.d.comb += [
        fifo.w_data.eq(fifo_data),
        fifo.w_en.eq(fifo_write),
        o.valid.eq(fifo.r_rdy),
        o.payload.eq(fifo.r_data),
        fifo.r_en.eq(o.ready),
    ]
    build_stash(m, stashes.links, dsp)


# --- iterative ----------------------------------------------------------------------------------

def _registered_stage(dp, m, stage, state, load, stage_valid, leave):
    out = stage.fn(state)
    regs = _registers(dp, stage.name, out)
    with m.If(leave):
        m.d.sync += stage_valid.eq(0)
    with m.If(load):
        m.d.sync += [regs[key].eq(out[key]) for key in regs]
        m.d.sync += stage_valid.eq(1)
    return regs, stage_valid


def _iterated_stage(dp, m, stage, state, load, stage_valid, leave):
    name, fn, count = stage.name, stage.fn, stage.count
    # The key set and shapes come from a probe call (pure: builds no hardware).
    regs = _registers(dp, name, fn(state, 0))
    step = Signal(range(count + 1), name=f"{name}_step")
    extra = set(state) - set(regs)
    if extra:
        raise ValueError(f"iterated stage {name!r} drops {sorted(extra)}")
    source = {key: Mux(load, state[key] if key in state else 0, regs[key]) for key in regs}
    out = fn(source, step)
    done = stage_valid & (step == count)
    with m.If(leave):
        m.d.sync += [stage_valid.eq(0), step.eq(0)]
    with m.If(load):
        m.d.sync += [regs[key].eq(out[key]) for key in regs]
        m.d.sync += [stage_valid.eq(1), step.eq(1)]
    with m.Elif(stage_valid & (step != count)):
        m.d.sync += [regs[key].eq(out[key]) for key in regs]
        m.d.sync += step.eq(step + 1)
    return regs, done


def build_iterative(dp, m, inputs, payload_of, i, o):
    # One item in flight: the stage holding it moves it on as soon as it is done, except the
    # last, which waits for o.ready.
    state = dict(inputs)
    load = Signal(name=f"{dp.name}_accept")
    m.d.comb += load.eq(i.valid & i.ready)
    occupied, leaves = [], []
    for stage in map(Stage.of, dp.stages):
        if stage.count == 0:
            state = stage.fn(state)
            continue
        stage_valid = Signal(name=f"{stage.name}_valid")
        leave = Signal(name=f"{stage.name}_leave")
        if not stage.iterated:
            state, done = _registered_stage(dp, m, stage, state, load, stage_valid, leave)
        else:
            state, done = _iterated_stage(dp, m, stage, state, load, stage_valid, leave)
        occupied.append(stage_valid)
        leaves.append((leave, done))
        load = Signal(name=f"{stage.name}_next")
        m.d.comb += load.eq(done)
    # The last stage leaves on an output transfer; the others as soon as they are done.
    for leave, done in leaves[:-1]:
        m.d.comb += leave.eq(done)
    last_leave, last_done = leaves[-1]
    busy = Signal(name=f"{dp.name}_busy")
    m.d.comb += [
        o.valid.eq(last_done),
        last_leave.eq(last_done & o.ready),
        busy.eq(Cat(*occupied).any()),
        i.ready.eq(~busy | (last_done & o.ready)),
    ]
    for field, value in payload_of(state).items():
        m.d.comb += getattr(o.payload, field).eq(value)

