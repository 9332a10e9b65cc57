"""Shared machinery of the ik5r arithmetic blocks: a staged datapath, stream blocks, helpers.

Every block (:class:`~ik5r.hdl.cordic.Atan2`, :class:`~ik5r.hdl.cordic.Rotate`,
:class:`~ik5r.hdl.sqrt.Sqrt`, :class:`~ik5r.hdl.acos.Acos`) describes its arithmetic once, as a
:class:`Datapath`: an ordered list of *stages*, each a pure function from a dictionary of named
values (the state carried by one item) to the next such dictionary. The same description is
elaborated in one of two architectures:

``"pipelined"``
    Every stage (and every repetition of an iterated stage) gets its own register set: one item
    enters per clock, results leave in order. The pipeline never stalls (no clock enable: one
    enable net to every flip-flop was the slowest path of the IK core); its results go into an
    output FIFO (block RAM), and ``o`` is the FIFO's read side. Flow control by credits: a counter
    of the FIFO's free slots, taken by an input transfer and given back by an output transfer,
    keeps items in flight plus items in the FIFO within its depth, so the FIFO never overflows
    while ``o`` is held, and the depth covers the latency, so at full rate no bubble appears.

``"iterative"``
    One item in flight. An iterated stage (CORDIC micro-rotation, square-root digit) is one
    register set fed back ``count`` times with a run-time step index; the other stages keep their
    own registers. A new item is accepted when the block is idle, or in the cycle its previous
    result leaves, so a result is produced every :attr:`Datapath.latency` cycles.

Both architectures evaluate literally the same expressions on the same widths, so they agree
bit for bit; the widths are derived from :class:`~ik5r.fxconfig.Constants` with proofs of no
overflow in the comments of each block.

Three options make a datapath smaller or faster without changing a bit of its results:

* ``Datapath(products="sequential")``: each multiplier of :func:`add_products` is one 18 x 18
  DSP stepped over its partial products into an accumulator, instead of one DSP per partial
  product and an adder tree (the compact IK core).
* ``Datapath(share_units=True)``: in the iterative architecture, every stage of one functional
  unit (:meth:`Datapath.add_shared_iter`, e.g. the CORDIC micro-rotation) runs on one set of
  registers and one copy of the logic (the compact IK core: eight CORDICs, one unit).
* ``build(..., dsp="ecp5")``: in the pipelined architecture, each partial product is an ECP5
  ``MULT18X18D`` whose input and output registers are the two pipeline registers around it, and
  each add-or-subtract (:func:`add_sub`, the CORDIC micro-rotations) is a ``CCU2C`` carry chain
  whose own LUTs take the direction (no XOR LUT in front of the chain).
"""

from __future__ import annotations

from amaranth.hdl import Cat, Const, Module, Mux, Shape, Signal, Value, ValueCastable, signed, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.fifo import SyncFIFOBuffered
from amaranth.lib.wiring import In, Out

from ik5r.fxconfig import Constants

__all__ = ["ARCHS", "DSPS", "ECP5_ADD_SUB_MODULE", "ecp5_add_sub", "ecp5_add_sub_verilog", "PRODUCTS", "LIMB_BITS", "Datapath", "SharedStage", "StreamBlock", "add_sub", "asr", "rshift_round", "saturate",
           "leading_zeros", "add_products", "table_entry", "drop"]

# The ECP5 primitives (CCU2C chains, MULT18X18D) live in .ecp5; their names stay importable here.
from .ecp5 import (CCU2C_ADD_SUB_INIT, ECP5_ADD_SUB_MODULE, MULT_BITS, carry_chains,  # noqa: E402,F401
                   ccu2c_add_sub, ecp5_add_sub, ecp5_add_sub_verilog, mult18x18d)
from .modes import ARCHS, DSPS, PRODUCTS  # noqa: E402 (defined once, in .modes)

# DSPS: how a pipelined datapath maps to the FPGA: portable operators (any FPGA; Yosys maps ``*``
# to a DSP without its registers), or ECP5 primitives: a ``MULT18X18D`` per partial product whose
# input and output registers are the two pipeline registers around it (the DSP's multiplier no
# longer sits between fabric flip-flops), and a ``CCU2C`` chain per :func:`add_sub`. Same
# latency, same bits. PRODUCTS: how a datapath multiplies (:func:`add_products`): all partial
# products at once, or one 18 x 18 partial product per clock step into an accumulator.

#: Operand slice width of a partial product: 17 x 17 unsigned (18 x 18 signed at the top limb)
#: fits one ECP5 MULT18X18D.
LIMB_BITS = 17
assert LIMB_BITS + 1 == MULT_BITS

#: Cycles from the last stage of the pipelined architecture to the item on ``o``: the register
#: in front of the output FIFO, then the FIFO's (``SyncFIFOBuffered``) RAM write and its RAM
#: read into the output register.
OUTPUT_FIFO_LATENCY = 3


# --- pure expression helpers ---------------------------------------------------------------------

def asr(value, amount):
    """``value >> amount``: arithmetic for a signed value, by an int or an unsigned Value."""
    value = Value.cast(value)
    if isinstance(amount, int):
        return value.shift_right(amount)
    return value >> amount


def _extend(value, width):
    """``value`` sign- (or zero-) extended to ``width`` bits, as raw bits."""
    fill = value[-1] if value.shape().signed else Const(0, 1)
    return Cat(value, fill.replicate(width - len(value)))


def add_sub(a, b, subtract):
    """``a - b`` if ``subtract`` else ``a + b``, with ONE adder (not two and a mux).

    ``(a << 1 | s) + ((b ^ s...s) << 1 | s)`` has ``a + (b ^ s...s) + s`` above its LSB: the
    carry-in is folded into the extra LSB. Exact: the result is a ``signed`` value wide enough
    for any ``a +- b``.

    Yosys maps the XOR to a LUT of its own in front of each carry cell (one LUT level and one
    route more than an adder: the CORDIC direction's path, and half of a micro-rotation's LUTs).
    Inside :func:`ecp5_add_sub` (a pipelined datapath built with ``dsp="ecp5"``) the same sum is
    an ECP5 ``CCU2C`` chain whose own LUTs take ``subtract`` as a third input
    (:func:`ecp5_add_sub_verilog`), as Yosys's own ``$alu`` mapping does with its B-invert input,
    which it never infers from this form.
    """
    a, b, subtract = Value.cast(a), Value.cast(b), Value.cast(subtract)
    width = max(len(a) + (not a.shape().signed), len(b) + (not b.shape().signed)) + 1
    chains = carry_chains()
    if chains is not None and not isinstance(subtract, Const):
        return ccu2c_add_sub(_extend(a, width), _extend(b, width), subtract, chains)
    inverted = _extend(b, width) ^ subtract.replicate(width)
    total = Cat(subtract, _extend(a, width)) + Cat(subtract, inverted)
    return total[1:width + 1].as_signed()


def rshift_round(value, shift: int, nearest: bool):
    """``value * 2**-shift`` by a constant shift, rounded half up (nearest) or floored.

    Exactly ``model.rshift_round``: one adder when ``nearest`` and ``shift > 0``, else wiring.
    """
    value = Value.cast(value)
    if shift <= 0:
        return value.shift_left(-shift)
    if nearest:
        value = value + (1 << (shift - 1))
    return value.shift_right(shift)


def saturate(value, width: int):
    """Clip ``value`` to the signed ``width``-bit range; returns ``(word, saturated)``.

    Pure logic (no comparator): the value fits iff its bits above ``width - 1`` are all copies
    of the sign. Exactly ``model.saturate``.
    """
    value = Value.cast(value)
    if len(value) <= width:
        return value, Const(0, 1)
    if not value.shape().signed:
        value = Cat(value, Const(0, 1)).as_signed()
    top = value[width - 1:]
    negative = value[-1]
    over = ~negative & top.any()
    under = negative & ~top.all()
    word_max = (1 << (width - 1)) - 1
    word_min = -(1 << (width - 1))
    clipped = Mux(over, Const(word_max, signed(width)),
                  Mux(under, Const(word_min, signed(width)), value[:width].as_signed()))
    return clipped, over | under


def _lzc_tree(value):
    """(all zero, leading zero count) of a power-of-two-wide value, as a balanced tree."""
    if len(value) == 1:
        return ~value[0], Const(0, 0)
    half = len(value) // 2
    zero_lo, count_lo = _lzc_tree(value[:half])
    zero_hi, count_hi = _lzc_tree(value[half:])
    count = Mux(zero_hi, Cat(count_lo, Const(1, 1)), Cat(count_hi, Const(0, 1)))
    return zero_hi & zero_lo, count


def leading_zeros(value):
    """Number of leading zero bits of an unsigned value of width n (n when it is zero).

    A tree of log2(n) mux levels. The value is padded on the LSB side with ``1 0 ... 0`` up to a
    power of two, so the padded value is never zero and its count is the answer.
    """
    value = Value.cast(value)
    size = 1
    while size < len(value) + 1:
        size *= 2
    pad = size - len(value)
    _, count = _lzc_tree(Cat(Const(1 << (pad - 1), pad), value))
    return count


def select(options, index):
    """``options[index]`` for an unsigned Value ``index``: a balanced tree of 2-way muxes on the
    index bits (0 past the end of ``options``).

    Not ``Array(...)[index]``: an Array becomes a ``casez`` in an ``always @*`` block in the
    Verilog, which reads only the (initialised) step register. Under IEEE 1800 semantics (Icarus
    -g2012, as cocotb builds) a declaration initialiser is no event, so that block does not run
    before the step first changes and the entry of step 0 is X for the first item after time 0.
    A mux is a continuous assignment: defined from time 0 on every simulator.
    """
    index = Value.cast(index)
    level = list(options) + [Const(0, 1)] * ((1 << len(index)) - len(options))
    for bit in range(len(index)):
        level = [Mux(index[bit], level[j + 1], level[j]) for j in range(0, len(level), 2)]
    return level[0]


def table_entry(table, index):
    """``table[index]`` for a constant table: a constant for an int index, else :func:`select`
    over the entries in the union of their shapes (0 past the end of the table)."""
    if isinstance(index, int):
        return Const(table[index])
    shapes = [Const(entry).shape() for entry in table]
    if any(s.signed for s in shapes):
        shape = signed(max(s.width + (not s.signed) for s in shapes))
    else:
        shape = unsigned(max(s.width for s in shapes))
    return select([Const(entry, shape) for entry in table], index)


def drop(state, *keys):
    """A copy of a state dictionary without ``keys``."""
    return {key: value for key, value in state.items() if key not in keys}


# --- the staged datapath -------------------------------------------------------------------------

class SharedStage:
    """What an iterated stage made by :meth:`Datapath.add_shared_iter` is: ``fn(unit_state, i)``
    of the functional unit ``unit`` (with register shapes ``shapes``) on the state keys (or
    constants) of ``binding`` (unit key -> state key | int)."""

    def __init__(self, unit, fn, binding, shapes):
        self.unit, self.fn, self.binding, self.shapes = unit, fn, dict(binding), dict(shapes)

    def prefixed(self, prefix: str) -> "SharedStage":
        return SharedStage(self.unit, self.fn, {u: prefix + k if isinstance(k, str) else k
                                                for u, k in self.binding.items()}, self.shapes)

    def stage_fn(self):
        """The stage as a plain ``fn(state, i) -> state`` (the unit's keys bound to the state's)."""
        def run(state, i):
            inner = {u: state[k] if isinstance(k, str) else k for u, k in self.binding.items()}
            result = self.fn(inner, i)
            out = dict(state)
            for u, k in self.binding.items():
                if isinstance(k, str):
                    out[k] = result[u]
            return out
        run.shared = self
        return run


class Datapath:
    """An ordered list of stages over named values; see the module docstring.

    ``add(name, fn)``: a registered stage, ``fn(state) -> state``.
    ``add_iter(name, fn, count)``: ``count`` repetitions of ``fn(state, i) -> state`` with ``i`` an
    int (pipelined, unrolled) or an unsigned Value (iterative, one step per clock).
    ``add_wiring(fn)``: a renaming with no register (zero latency; ``fn`` must be wiring only).

    A stage's functions must be pure: they build expressions and never add statements. Values
    named by :meth:`declare` are stored in their declared shape (the blocks prove the values fit),
    others in the shape of their expression (never lossy).
    """

    def __init__(self, name: str, *, products: str = "parallel", share_units: bool = False):
        if products not in PRODUCTS:
            raise ValueError(f"products must be one of {PRODUCTS}, got {products!r}")
        self.name = name
        #: How :func:`add_products` builds a multiplier in this datapath (see there).
        self.products = products
        #: Whether the iterative build gives all stages of one functional unit
        #: (:meth:`add_shared_iter`) one register set and one copy of its logic.
        self.share_units = share_units
        self.stages = []
        self.shapes = {}

    def declare(self, **shapes):
        for key, shape in shapes.items():
            self.shapes[key] = Shape.cast(shape)

    def add(self, name, fn):
        self.stages.append((name, fn, 1, False))

    def add_iter(self, name, fn, count: int):
        if count < 1:
            raise ValueError(f"stage {name!r}: count must be at least 1, got {count}")
        self.stages.append((name, fn, count, True))

    def add_shared_iter(self, name, unit: SharedStage, count: int):
        """``add_iter`` of a functional unit's step (see :class:`SharedStage`). Pipelined, and
        iterative without ``share_units``: the same as ``add_iter``. Iterative with
        ``share_units``: every stage of the same ``unit.unit`` uses one set of the unit's
        registers and one copy of ``unit.fn`` (one item in flight, so one user at a time); the
        other keys are not copied (their registers hold until the item leaves). A shared stage
        must be followed by a registered, non-iterated stage, which takes its results."""
        self.add_iter(name, unit.stage_fn(), count)

    def add_wiring(self, fn):
        self.stages.append(("wiring", fn, 0, False))

    @property
    def latency(self) -> int:
        """Register stages of the datapath: cycles from an input transfer to the result in the
        last stage's registers."""
        return sum(count for _, _, count, _ in self.stages)

    def stream_latency(self, arch: str) -> int:
        """Cycles from an input transfer to its result on ``o`` when ``o`` is not held: the
        stages, and in the pipelined architecture the output FIFO."""
        return self.latency + (OUTPUT_FIFO_LATENCY if arch == "pipelined" else 0)

    def capacity(self, arch: str) -> int:
        """Items the built block holds at most (accepted, not yet taken from ``o``); while ``o``
        is held it accepts this many, then ``i.ready`` stays low. Pipelined: the depth of the
        output FIFO, one more than a power of two at least the stream latency (the credit that
        lets an item in is registered, so one slot more than the items a full-rate stream keeps
        in flight; ``SyncFIFOBuffered`` holds one item in its output register and the rest in a
        RAM, whose pointers then wrap for free). Iterative: one."""
        if arch != "pipelined":
            return 1
        return (1 << (self.stream_latency(arch) - 1).bit_length()) + 1

    def _registers(self, prefix, values):
        regs = {}
        for key, value in values.items():
            shape = self.shapes.get(key, Value.cast(value).shape())
            regs[key] = Signal(shape, name=f"{prefix}_{key}", reset_less=True)
        return regs

    def build(self, m: Module, arch: str, inputs: dict, payload_of, i, o, dsp: str = "generic") -> None:
        """Elaborate into ``m`` between the streams ``i`` (its payload already turned into the
        state ``inputs``) and ``o``, whose payload fields ``payload_of(final_state) -> {field:
        value}`` gives. ``dsp`` (one of :data:`DSPS`) applies to the pipelined architecture."""
        if dsp not in DSPS:
            raise ValueError(f"dsp must be one of {DSPS}, got {dsp!r}")
        if arch == "pipelined":
            self._build_pipelined(m, inputs, payload_of, i, o, dsp)
        elif arch == "iterative":
            self._build_iterative(m, inputs, payload_of, i, o)
        else:
            raise ValueError(f"arch must be one of {ARCHS}, got {arch!r}")

    def _build_pipelined(self, m, inputs, payload_of, i, o, dsp):
        # The credits: free slots of the output FIFO not yet promised to an item in flight.
        depth = self.capacity("pipelined")
        credits = Signal(range(depth + 1), init=depth, name=f"{self.name}_credits")
        # ``credits != 0``, kept in a register of its own: ``i.ready`` is a flip-flop output.
        has_credit = Signal(init=1, name=f"{self.name}_has_credit")
        fifo = m.submodules[f"{self.name}_output_fifo"] = SyncFIFOBuffered(
            width=o.payload.shape().size, depth=depth)
        taken_in = Signal(name=f"{self.name}_taken_in")
        taken_out = Signal(name=f"{self.name}_taken_out")
        m.d.comb += [
            i.ready.eq(has_credit),
            taken_in.eq(i.valid & has_credit),
            taken_out.eq(fifo.r_rdy & o.ready),
        ]
        with m.If(taken_in & ~taken_out):
            m.d.sync += [credits.eq(credits - 1), has_credit.eq(credits != 1)]
        with m.Elif(taken_out & ~taken_in):
            m.d.sync += [credits.eq(credits + 1), has_credit.eq(1)]

        state, valid = dict(inputs), taken_in
        # What each register of the previous stage is loaded with (for the ECP5 DSP mapping).
        loaded = {}
        for name, fn, count, iterated in self.stages:
            if count == 0:
                state = fn(state)
                continue
            for step in range(count):
                prefix = f"{name}{step}" if iterated else name
                with ecp5_add_sub(dsp == "ecp5") as chains:
                    out = fn(state, step) if iterated else fn(state)
                for index, cell in enumerate(chains or ()):
                    m.submodules[f"{prefix}_add_sub{index}"] = cell
                regs = self._registers(prefix, out)
                stage_valid = Signal(name=f"{prefix}_valid")
                plain = list(regs)
                if dsp == "ecp5":
                    for key in regs:
                        if isinstance(out[key], _Product) and out[key].map_ecp5(
                                m, f"{prefix}_{key}", regs[key], loaded):
                            plain.remove(key)
                m.d.sync += [regs[key].eq(out[key]) for key in plain]
                m.d.sync += stage_valid.eq(valid)
                loaded = {id(regs[key]): (regs[key], out[key]) for key in regs}
                state, valid = regs, stage_valid

        payload = Signal(o.payload.shape(), name=f"{self.name}_result")
        for field, value in payload_of(state).items():
            m.d.comb += getattr(payload, field).eq(value)
        # A register in front of the FIFO, placed next to it: the FIFO's RAMs sit in block RAM
        # rows far from the end of a large pipeline, and the FIFO's level counter, which reads
        # the write enable, got a long route there and back (the IK core's slowest path).
        fifo_data = Signal.like(payload, name=f"{self.name}_fifo_data", reset_less=True)
        fifo_write = Signal(name=f"{self.name}_fifo_write")
        m.d.sync += [fifo_data.eq(payload), fifo_write.eq(valid)]
        m.d.comb += [
            fifo.w_data.eq(fifo_data),
            fifo.w_en.eq(fifo_write),
            o.valid.eq(fifo.r_rdy),
            o.payload.eq(fifo.r_data),
            fifo.r_en.eq(o.ready),
        ]

    def _build_iterative(self, m, inputs, payload_of, i, o):
        # One item in flight: the stage holding it moves it on as soon as it is done, except the
        # last, which waits for o.ready.
        i_valid, i_ready, o_valid, o_ready = i.valid, i.ready, o.valid, o.ready
        state = dict(inputs)
        load = Signal(name=f"{self.name}_accept")
        m.d.comb += load.eq(i_valid & i_ready)
        occupied, leaves = [], []
        units = {}
        previous_shared = False
        for name, fn, count, iterated in self.stages:
            if count == 0:
                state = fn(state)
                continue
            stage_valid = Signal(name=f"{name}_valid")
            leave = Signal(name=f"{name}_leave")
            shared = getattr(fn, "shared", None) if iterated and self.share_units else None
            if previous_shared and (iterated or count != 1):
                raise ValueError(f"stage {name!r} follows a shared stage: must be a registered one")
            previous_shared = shared is not None
            if shared is not None:
                unit = units.get(shared.unit)
                if unit is None:
                    unit = units[shared.unit] = _SharedUnit(shared, count)
                if unit.count != count or unit.shapes != shared.shapes:
                    raise ValueError(f"stage {name!r}: unit {shared.unit!r} used with other counts/shapes")
                inputs = {u: state[k] if isinstance(k, str) else Const(k, shared.shapes[u])
                          for u, k in shared.binding.items()}
                unit.users.append((load, inputs, stage_valid, leave))
                done = stage_valid & (unit.step == count)
                with m.If(leave):
                    m.d.sync += stage_valid.eq(0)
                with m.If(load):
                    m.d.sync += stage_valid.eq(1)
                regs = dict(state)
                regs.update({k: unit.regs[u] for u, k in shared.binding.items() if isinstance(k, str)})
            elif not iterated:
                out = fn(state)
                regs = self._registers(name, out)
                done = stage_valid
                with m.If(leave):
                    m.d.sync += stage_valid.eq(0)
                with m.If(load):
                    m.d.sync += [regs[key].eq(out[key]) for key in regs]
                    m.d.sync += stage_valid.eq(1)
            else:
                # The key set and shapes come from a probe call (pure: builds no hardware).
                regs = self._registers(name, fn(state, 0))
                step = Signal(range(count + 1), name=f"{name}_step")
                extra = set(state) - set(regs)
                if extra:
                    raise ValueError(f"iterated stage {name!r} drops {sorted(extra)}")
                source = {key: Mux(load, state[key] if key in state else 0, regs[key])
                          for key in regs}
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
            occupied.append(stage_valid)
            leaves.append((leave, done))
            state = regs
            load = Signal(name=f"{name}_next")
            m.d.comb += load.eq(done)
        for unit in units.values():
            unit.elaborate(m)
        # The last stage leaves on an output transfer; the others as soon as they are done.
        for leave, done in leaves[:-1]:
            m.d.comb += leave.eq(done)
        last_leave, last_done = leaves[-1]
        busy = Signal(name=f"{self.name}_busy")
        m.d.comb += [
            o_valid.eq(last_done),
            last_leave.eq(last_done & o_ready),
            busy.eq(Cat(*occupied).any()),
            i_ready.eq(~busy | (last_done & o_ready)),
        ]
        for field, value in payload_of(state).items():
            m.d.comb += getattr(o.payload, field).eq(value)


class _SharedUnit:
    """The registers, step counter and logic of one shared functional unit (iterative build)."""

    def __init__(self, shared: SharedStage, count: int):
        self.fn, self.count, self.shapes = shared.fn, count, shared.shapes
        self.regs = {u: Signal(shape, name=f"unit_{shared.unit}_{u}", reset_less=True)
                     for u, shape in shared.shapes.items()}
        self.step = Signal(range(count + 1), name=f"unit_{shared.unit}_step")
        self.users = []       # (load, inputs, stage_valid, leave)

    def elaborate(self, m):
        source = dict(self.regs)
        for load, inputs, _, _ in reversed(self.users):
            source = {u: Mux(load, inputs[u], value) if u in inputs else value
                      for u, value in source.items()}
        out = self.fn(source, self.step)
        loading = Cat(*(load for load, _, _, _ in self.users)).any()
        active = Cat(*(valid for _, _, valid, _ in self.users)).any()
        leaving = Cat(*(leave for _, _, _, leave in self.users)).any()
        with m.If(leaving):
            m.d.sync += self.step.eq(0)
        with m.If(loading):
            m.d.sync += [self.regs[u].eq(out[u]) for u in self.regs]
            m.d.sync += self.step.eq(1)
        with m.Elif(active & (self.step != self.count)):
            m.d.sync += [self.regs[u].eq(out[u]) for u in self.regs]
            m.d.sync += self.step.eq(self.step + 1)


# --- partial-product multipliers -----------------------------------------------------------------

class _Product(ValueCastable):
    """One partial product ``(a[a_lo:a_hi] * b_part) << shift`` of registered operands; ``b_part``
    is a non-negative constant below 2**LIMB_BITS or a ``(b, lo, hi, signed)`` slice. As a value it
    is that expression; :meth:`map_ecp5` builds it as a ``MULT18X18D`` instead."""

    def __init__(self, a, a_range, b_part, shift):
        self.a, self.a_range, self.b_part, self.shift = a, a_range, b_part, shift
        a_part = _slice(a, *a_range)
        if isinstance(b_part, int):
            b_value = Const(b_part, unsigned(max(b_part.bit_length(), 1)))
        else:
            b_value = _slice(b_part[0], *b_part[1:])
        self._value = (a_part * b_value).shift_left(shift)

    def as_value(self):
        return self._value

    def shape(self):
        return self._value.shape()

    def map_ecp5(self, m, name, target, loaded) -> bool:
        """Drive ``target`` from a ``MULT18X18D`` with input and output registers (always
        enabled, as the pipeline), fed by what the previous stage's registers ``a`` (and ``b``)
        were loaded with; False (nothing built) when an operand is not such a register."""
        if id(self.a) not in loaded:
            return False
        a_reg, a_next = loaded[id(self.a)]
        a_src = Signal(a_reg.shape(), name=f"{name}_a")
        m.d.comb += a_src.eq(a_next)
        if isinstance(self.b_part, int):
            b18 = Const(self.b_part, signed(LIMB_BITS + 1))
        else:
            b, lo, hi, is_signed = self.b_part
            if id(b) not in loaded:
                return False
            b_reg, b_next = loaded[id(b)]
            b_src = Signal(b_reg.shape(), name=f"{name}_b")
            m.d.comb += b_src.eq(b_next)
            b18 = _limb18(b_src, lo, hi, is_signed)
        a18 = _limb18(a_src, *self.a_range)
        product = mult18x18d(m, name, a18, b18)
        m.d.comb += target.eq(product.shift_left(self.shift))
        return True


def _limbs(shape: Shape):
    """Bit ranges (lo, hi, signed) of LIMB_BITS-wide slices of an operand; top one keeps sign."""
    width = shape.width
    ranges = []
    for lo in range(0, width, LIMB_BITS):
        hi = min(lo + LIMB_BITS, width)
        ranges.append((lo, hi, shape.signed and hi == width))
    return ranges


def _slice(value, lo, hi, is_signed):
    part = Value.cast(value)[lo:hi]
    return part.as_signed() if is_signed else part


def add_products(dp: Datapath, prefix: str, specs, *, parallel=None, drop_keys=()):
    """Append the stages of one or more parallel multipliers ``a * b`` to ``dp``.

    ``specs``: list of ``(a_of, a_shape, b, out_key)``; ``a_of(state)`` gives operand a (which
    must fit ``a_shape``); ``b`` is a non-negative int constant or ``(b_of, b_shape)``.

    Stage 1 registers the operands (in their shapes), stage 2 forms the LIMB_BITS x LIMB_BITS
    partial products (one DSP each, nothing else in the stage); each further stage adds pairs of
    partial sums (one adder level), until one sum per multiplier is left under ``out_key``.
    ``parallel(state) -> dict`` adds other work to stage 1 (e.g. a rounding), and ``drop_keys``
    are removed from the state at stage 1. Returns the number of stages.

    In a ``products="sequential"`` datapath, stage 1 also clears one accumulator per multiplier,
    and one iterated stage adds one 18 x 18 signed partial product per step (the limb pair and
    its weight chosen by the step index): one DSP per multiplier instead of one per partial
    product, for as many steps as the largest multiplier has partial products. The sum is the
    same exact integer, so the two forms agree bit for bit.
    """
    if dp.products == "sequential":
        return _add_products_sequential(dp, prefix, specs, parallel, drop_keys)
    trees = []
    for index, (a_of, a_shape, b, out_key) in enumerate(specs):
        a_shape = Shape.cast(a_shape)
        terms = []
        if isinstance(b, int):
            if b < 0:
                raise ValueError("constant multiplier must be non-negative")
            for a_lo, a_hi, a_signed in _limbs(a_shape):
                for b_lo in range(0, max(b.bit_length(), 1), LIMB_BITS):
                    b_part = (b >> b_lo) & ((1 << LIMB_BITS) - 1)
                    if b_part:
                        terms.append((f"{prefix}{index}_p{len(terms)}", a_lo + b_lo,
                                      (a_lo, a_hi, a_signed), b_part))
        else:
            b_of, b_shape = b
            for a_lo, a_hi, a_signed in _limbs(a_shape):
                for b_lo, b_hi, b_signed in _limbs(Shape.cast(b_shape)):
                    terms.append((f"{prefix}{index}_p{len(terms)}", a_lo + b_lo,
                                  (a_lo, a_hi, a_signed), (b_of, b_lo, b_hi, b_signed)))
        trees.append((a_of, out_key, terms))

    # Stage 1 registers the operands: a register next to the DSPs, so that the stage holding a
    # DSP has only the DSP's own delay (the DSP registers themselves are not inferred).
    for index, (_, a_shape, b, _) in enumerate(specs):
        dp.declare(**{f"{prefix}{index}_a": a_shape})
        if not isinstance(b, int):
            dp.declare(**{f"{prefix}{index}_b": b[1]})

    def operands(state):
        out = drop(state, *drop_keys)
        for index, (a_of, _, b, _) in enumerate(specs):
            out[f"{prefix}{index}_a"] = a_of(state)
            if not isinstance(b, int):
                out[f"{prefix}{index}_b"] = b[0](state)
        if parallel is not None:
            out.update(parallel(state))
        return out

    def products(state):
        out = dict(state)
        for index, (_, out_key, terms) in enumerate(trees):
            a = out.pop(f"{prefix}{index}_a")
            b = out.pop(f"{prefix}{index}_b", None)
            if not terms:
                out[out_key] = Const(0, 1)
            for key, shift, a_range, b_part in terms:
                if not isinstance(b_part, int):
                    b_part = (b,) + b_part[1:]
                # A single product is the result: it keeps its weight; terms of a sum get theirs
                # in the adder tree.
                out[key] = _Product(a, a_range, b_part, shift if len(terms) == 1 else 0)
            if len(terms) == 1:
                out[out_key] = out.pop(terms[0][0])
        return out

    dp.add(f"{prefix}_op", operands)
    dp.add(f"{prefix}_mul", products)
    # Adder tree: each level adds adjacent (by weight) pairs of terms; an odd one passes through.
    pending = {out_key: [(key, shift) for key, shift, _, _ in terms]
               for _, out_key, terms in trees if len(terms) > 1}
    depth = 0
    while pending:
        plan = {}
        for out_key, terms in pending.items():
            terms = sorted(terms, key=lambda term: term[1])
            plan[out_key] = [terms[pair:pair + 2] for pair in range(0, len(terms), 2)]

        def level(state, plan=plan):
            out = dict(state)
            for out_key, groups in plan.items():
                sums = []
                for group in groups:
                    base = min(shift for _, shift in group)
                    total = None
                    for key, shift in group:
                        term = Value.cast(out.pop(key)).shift_left(shift - base)
                        total = term if total is None else total + term
                    sums.append((f"{group[0][0]}s", base, total))
                if len(sums) == 1:
                    _, base, total = sums[0]
                    out[out_key] = total.shift_left(base)
                else:
                    out.update({key: total for key, _, total in sums})
            return out

        dp.add(f"{prefix}_sum{depth}", level)
        depth += 1
        pending = {out_key: [(f"{group[0][0]}s", min(shift for _, shift in group))
                             for group in groups]
                   for out_key, groups in plan.items() if len(groups) > 1}
    return 2 + depth


def _limb18(value, lo, hi, is_signed):
    """Bits [lo, hi) of ``value`` as a ``signed(LIMB_BITS + 1)`` multiplier operand."""
    part = _slice(value, lo, hi, is_signed)
    return _extend(part, LIMB_BITS + 1).as_signed()


def _add_products_sequential(dp, prefix, specs, parallel, drop_keys):
    """The ``products="sequential"`` form of :func:`add_products`."""
    plans = []
    for index, (a_of, a_shape, b, out_key) in enumerate(specs):
        a_shape = Shape.cast(a_shape)
        steps = []
        if isinstance(b, int):
            if b < 0:
                raise ValueError("constant multiplier must be non-negative")
            b_width = max(b.bit_length(), 1) + 1
            for a_range in _limbs(a_shape):
                for b_lo in range(0, max(b.bit_length(), 1), LIMB_BITS):
                    b_part = (b >> b_lo) & ((1 << LIMB_BITS) - 1)
                    if b_part:
                        steps.append((a_range, b_part, a_range[0] + b_lo))
        else:
            b_width = Shape.cast(b[1]).width + 1
            for a_range in _limbs(a_shape):
                for b_range in _limbs(Shape.cast(b[1])):
                    steps.append((a_range, b_range, a_range[0] + b_range[0]))
        # Any partial sum of the terms is below 2**(a_width + b_width) in magnitude.
        dp.declare(**{out_key: signed(a_shape.width + 1 + b_width + 1),
                      f"{prefix}{index}_a": a_shape})
        if not isinstance(b, int):
            dp.declare(**{f"{prefix}{index}_b": b[1]})
        plans.append((a_of, b, out_key, steps))
    count = max(len(steps) for *_, steps in plans)

    def operands(state):
        out = drop(state, *drop_keys)
        for index, (a_of, b, out_key, _) in enumerate(plans):
            out[f"{prefix}{index}_a"] = a_of(state)
            if not isinstance(b, int):
                out[f"{prefix}{index}_b"] = b[0](state)
            out[out_key] = Const(0, 1)
        if parallel is not None:
            out.update(parallel(state))
        return out

    def accumulate(state, step):
        out = dict(state)
        for index, (_, b, out_key, steps) in enumerate(plans):
            a = state[f"{prefix}{index}_a"]
            b_value = None if isinstance(b, int) else state[f"{prefix}{index}_b"]

            def b_limb(b_part):
                if isinstance(b_part, int):
                    return Const(b_part, signed(LIMB_BITS + 1))
                return _limb18(b_value, *b_part)

            if isinstance(step, int):
                if step >= len(steps):
                    continue
                a_range, b_part, shift = steps[step]
                term = (_limb18(a, *a_range) * b_limb(b_part)).shift_left(shift)
            else:
                # Past the last step the b operand is 0, so the term is 0.
                product = (select([_limb18(a, *a_range) for a_range, _, _ in steps], step)
                           * select([b_limb(b_part) for _, b_part, _ in steps], step))
                term = select([product.shift_left(shift) for _, _, shift in steps], step)
            out[out_key] = state[out_key] + term
        return out

    dp.add(f"{prefix}_op", operands)
    dp.add_iter(f"{prefix}_acc", accumulate, count)
    dp.add_wiring(lambda state: drop(state, *(f"{prefix}{index}_{side}" for index in range(len(plans))
                                              for side in "ab")))
    return 1 + count


# --- the stream block base class -----------------------------------------------------------------

def check_common(constants, arch, tag_width, dsp="generic"):
    if not isinstance(constants, Constants):
        raise TypeError(f"constants must be an ik5r.fxconfig.Constants, got {constants!r}")
    if arch not in ARCHS:
        raise ValueError(f"arch must be one of {ARCHS}, got {arch!r}")
    if isinstance(tag_width, bool) or not isinstance(tag_width, int) or tag_width < 0:
        raise ValueError(f"tag_width must be a non-negative integer, got {tag_width!r}")
    if dsp not in DSPS:
        raise ValueError(f"dsp must be one of {DSPS}, got {dsp!r}")
    if dsp != "generic" and arch != "pipelined":
        raise ValueError(f"dsp={dsp!r} applies to the pipelined architecture, not {arch!r}")


class StreamBlock(wiring.Component):
    """Base of the arithmetic blocks: ``i``/``o`` streams of struct payloads around a Datapath.

    Flow control. ``"pipelined"``: the pipeline never stalls; results queue in an output FIFO
    (block RAM) of ``capacity`` entries, read through ``o``. ``i.ready`` is low only while
    ``capacity`` items are inside (in flight or queued): when ``o`` is held, the block takes
    ``capacity`` more items, then waits; when ``o`` is taken every cycle it takes one item per
    clock, never lowering ``i.ready``. ``"iterative"``: one item inside (``capacity`` = 1).

    Subclasses set ``self._dp`` (the datapath), ``in_fields``/``out_fields`` (dicts name ->
    ``(shape, frac, description)``; frac is the number of fraction bits or ``None`` when the
    field is format-agnostic) and implement ``_inputs(payload) -> state`` and
    ``_outputs(state) -> {field: value}``.
    """

    def __init__(self, *, constants, arch, tag_width, in_fields, out_fields, datapath,
                 dsp="generic"):
        check_common(constants, arch, tag_width, dsp)
        self.constants = constants
        self.arch = arch
        self.tag_width = tag_width
        #: Multiplier mapping of the pipelined architecture, one of :data:`DSPS`.
        self.dsp = dsp
        if dsp != "generic":
            self.options = dict(getattr(self, "options", {}), dsp=dsp)
        if tag_width:
            in_fields = dict(in_fields, tag=(unsigned(tag_width), 0, "carried unchanged to o.tag"))
            out_fields = dict(out_fields, tag=(unsigned(tag_width), 0, "i.tag of the same item"))
        self.in_fields = in_fields
        self.out_fields = out_fields
        self._dp = datapath
        #: The architecture the datapath is built in (a subclass may name its own differently).
        self._datapath_arch = arch
        #: Cycles from an input transfer (cycle c) to its result on the output (cycle c + latency)
        #: when the output is not held.
        self.latency = datapath.stream_latency(arch)
        #: Clock cycles per result at full rate (1 pipelined; latency iterative).
        self.cycles_per_result = 1 if arch == "pipelined" else datapath.latency
        #: Items the block holds at most: while ``o`` is held it accepts this many.
        self.capacity = datapath.capacity(arch)
        super().__init__({
            "i": In(stream.Signature(data.StructLayout(
                {name: shape for name, (shape, _, _) in in_fields.items()}))),
            "o": Out(stream.Signature(data.StructLayout(
                {name: shape for name, (shape, _, _) in out_fields.items()}))),
        })

    def _inputs(self, payload) -> dict:
        raise NotImplementedError

    def _outputs(self, state) -> dict:
        raise NotImplementedError

    def _payload(self, final) -> dict:
        """The output payload fields of the datapath's final state (tag included)."""
        outputs = self._outputs(final)
        if self.tag_width:
            outputs["tag"] = final["tag"]
        return outputs

    def elaborate(self, platform):
        m = Module()
        state = self._inputs(self.i.payload)
        if self.tag_width:
            state["tag"] = self.i.payload.tag
        self._dp.build(m, self._datapath_arch, state, self._payload, self.i, self.o, self.dsp)
        return m
