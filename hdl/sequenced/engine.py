"""The sequenced IK engine: a small machine stepping :func:`~ik5r.hdl.sequenced.program.ik_program`.

:class:`SeqEngine` has word ports (one input word or one output word per instruction);
:class:`SequencedIKCore` puts the IK core's struct streams around it (the ``compact`` arch of
``IKCore``'s payloads), :class:`.serial.SerialIK` a narrow word-serial stream on each side (for
small FPGAs with few pins). The instruction set and its clock-exact reference are :mod:`.seq_isa`.

Pipeline: the program counter addresses the instruction ROM (block RAM, registered), whose output
addresses the data memory and the CORDIC step-angle ROM; their outputs are registered again, and
the instruction executes from its own register two clocks after the read (``READ_AHEAD``), so
every unit reads registers only (a block RAM's clock-to-output is ~6 ns on an ECP5). A wait on a word
port (no input word, output not taken) holds every register, including the RAM outputs.

The slowest paths are the two one-clock loops of arithmetic: the accumulator's adder (its right
operand a one-hot select of its own few sources, :data:`~.seq_isa.ADDER_SOURCES`, not the B bus
with its input word and CORDIC registers; the sum and the compare enter the accumulator, F and
status muxes last) and a CORDIC micro-rotation (a barrel shifter of 4-way stages, each with its
own shift register, into the x or y adder).
"""

from __future__ import annotations

from amaranth.hdl import Cat, Const, Module, Mux, Signal, Value, signed, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from ik5r.core.fxconfig import Constants
from ik5r.core.modes import CoreArch, Dsp

from . import isa as X
from ..graph.inputs import FLAG_FIELDS, INPUT_WORDS, WORD_FIELDS, tagged_fields
from ..datapath.expr import select
from . import units as U
from .program import POSES, ik_program
from .poses import PoseRegisters
from .units import STATUS_BITS

__all__ = ["SeqEngine", "SequencedIKCore", "STATUS_BITS"]


def _first(code: list, io) -> int:
    """The clock of the first pose's word port operation ``io``."""
    return next(t for t, ins in enumerate(code) if ins.io == io and not ins.ip)


class SeqEngine(wiring.Component):
    """The sequenced IK engine (see the module docstring), with word ports.

    Input: the program asks for word ``in_index`` (of the instruction executing next; 0..12:
    :data:`~.seq_isa.INPUT_WORDS`, 13: the flags word has_roll | shoulder_back << 1 |
    elbow_down << 2 | tag << 3) and takes it in a clock with ``in_valid`` high (``in_take``).
    Output: ``out_valid`` with word ``out_index`` (0..4: q1..q5, 5: status | tag << 6, status
    the :data:`STATUS_BITS` bits of :mod:`ik5r.core.status`) in ``out_data``, held until
    ``out_ready``. One run of the program takes ``cycles`` clocks when neither port waits.
    ``booted`` rises two clocks after reset, when the first instruction is about to execute.
    ``wide_product``: each product step multiplies a 16-bit limb of MA by 31 bits of MB (two
    DSPs): fewer clocks per pose, a longer product path. ``poses`` 2: a run computes two poses
    (:mod:`.poses`), the first's words, then the second's; at the second's first word the engine
    does not wait: without ``in_valid`` that pose is skipped (its words not taken, its output
    words not offered, ``out_valid`` low) until the next run. A cyclic program (a modulo
    schedule, :mod:`.modulo`: each pose runs on into the next run) skips the first pose too
    while another is in flight, and waits at its first word only when none is. ``dsp`` ecp5: the limb multiplier
    on ``MULT18X18D`` primitives whose input registers are the limb registers (the same clocks
    and bits; for ECP5 builds only, as the Amaranth simulator cannot run a primitive).
    """

    def __init__(self, *, constants: Constants, tag_width: int = 0, wide_product: bool = False,
                 poses: int = 1, dsp: str = Dsp.GENERIC):
        if not isinstance(constants, Constants):
            raise TypeError(f"constants must be an ik5r.core.fxconfig.Constants, got {constants!r}")
        check_wide(wide_product)
        _check_poses(poses)
        self.dsp = check_dsp(dsp)
        self.prog = ik_program(constants, wide_product=wide_product, poses=poses)
        clash = X.read_write_clash(self.prog.code)
        if clash is not None:
            raise ValueError(f"instruction {clash} writes the memory word that instruction "
                             f"{(clash + X.READ_AHEAD) % len(self.prog.code)} reads in the same clock")
        if any(i.alu in X.ADDING and (i.bsel or X.B_MEM) not in X.ADDER_SOURCES for i in self.prog.code):
            raise ValueError(f"the program adds a B-bus source outside {X.ADDER_SOURCES} (seq_isa.ADDER_SOURCES)")
        self.widths = w = self.prog.widths
        w.tag = tag_width
        self.cycles = len(self.prog.code)
        self.poses = poses
        #: The first pose's status word: its last output (in a cyclic program, in the next run
        #: if it comes before the pose's flags word).
        self.first_status = _first(self.prog.code, X.IO_STATUS)
        if self.prog.cyclic and self.first_status < _first(self.prog.code, X.IO_FLAGS):
            self.first_status += self.cycles
        self.in_bits = max(w.word, 3 + tag_width)
        #: STATUS_BITS, or 7 for an arm with limits (OUT_OF_LIMITS): the tag sits above them.
        self.status_bits = w.status = constants.status_width
        self.out_bits = max(w.word, self.status_bits + tag_width)
        super().__init__({
            "in_index": Out(unsigned(4)), "in_valid": In(1), "in_data": In(unsigned(self.in_bits)),
            "in_take": Out(1), "in_ready": Out(1), "booted": Out(1),
            "out_valid": Out(1), "out_ready": In(1), "out_index": Out(unsigned(3)),
            "out_data": Out(unsigned(self.out_bits)),
        })

    def elaborate(self, platform):
        m = Module()
        prog, w = self.prog, self.widths
        stall = Signal()
        pc, fetch, pre, ins = self._fetch(m, stall)
        dec, shift = self._decode(m, pre, stall)
        mem_q, step, mem_wr = self._memories(m, fetch, stall)

        # Compares, not an m.Switch: a Switch becomes a Verilog ``always @*`` process, which
        # Icarus runs only when an input changes, and ``exe``, its input, changes only when the
        # stall it decides is low: the stall stayed X and the core never started on Icarus.
        reading, writing = Signal(name="io_reading"), Signal(name="io_writing")
        m.d.comb += [reading.eq((ins.io == X.IO_IN) | (ins.io == X.IO_FLAGS)),
                     writing.eq((ins.io == X.IO_OUT) | (ins.io == X.IO_STATUS))]
        run = ~stall

        acc = Signal(signed(w.acc))
        regs = U.registers(w, self.dsp)
        # The word ports: ``(in_take, in_ready, out_valid)``.
        if prog.poses == 1:
            m.d.comb += stall.eq((reading & ~self.in_valid) | (writing & ~self.out_ready))
            pose_regs, io = None, (reading & run, reading, writing)
        else:
            pose_regs = PoseRegisters(regs, prog.poses, w, prog.cyclic)
            pose_stall, *io = pose_regs.ports(m, ins, self.in_valid, self.out_ready, run)
            m.d.comb += stall.eq(pose_stall)
        in_word = self.in_data[:w.word].as_signed().shift_left(w.guard)
        bus = Signal(signed(w.acc), name="bus")
        options = [mem_q, in_word, regs["cx"], regs["cy"], regs["cz"], regs["root"], regs["rem"], acc]
        # One-hot AND-OR (the select is decoded ahead): one LUT level per few sources.
        terms = [Mux(dec[f"bus{index}"], value, 0) for index, value in enumerate(options)]
        total_bus = terms[0]
        for term in terms[1:]:
            total_bus = total_bus | term
        m.d.comb += bus.eq(total_bus)
        flags = [pose_regs.of(name, ins.cp) if pose_regs else regs[name] for name in ("back", "down", "roll")]
        sources = [Const(1, 1), regs["flag"], *flags, regs["zero"]]
        cond = ((select(sources, Value.cast(ins.ca)) ^ ins.cai)
                & (select(sources, Value.cast(ins.cb)) ^ ins.cbi))
        #: The registers by name, for test benches that trace the engine.
        self.trace = dict(regs, acc=acc, pc=pc, exe=ins, bus=bus)
        U.alu(m, ins, dec, acc, bus, mem_q, cond, regs, run, w, prog.acc_shifts, pose_regs)
        U.cordic(m, ins, dec, shift, bus, cond, step, regs, run, w)
        U.multiplier(m, ins, pre.sh, bus, regs, run, w, prog.shifts, self.dsp)
        U.sqrt(m, ins, acc, regs, run, w)
        m.d.comb += [mem_wr.addr.eq(ins.wa), mem_wr.data.eq(acc), mem_wr.en.eq(ins.wr & run)]

        self._ports(m, ins, pre, stall, io, acc, regs, run, w, pose_regs)
        return m

    def _fetch(self, m, stall):
        """The program counter, the instruction ROM (of :func:`.isa.word_layout` words) and the
        two instruction registers: (pc, the ROM's output, ``fetched``, ``exe``)."""
        layout = X.word_layout(self.prog.code)
        words = [X.encode(layout, ins) for ins in self.prog.code]
        # ``started`` is low in the first clock after power-up or reset, when the ROM's output
        # is not yet instruction 0: the program counter stays at 0 and a no-op executes.
        started = Signal()
        m.d.sync += [started.eq(1), self.booted.eq(started)]
        pc = Signal(range(len(words)))
        pc_next = Mux(stall | ~started, pc, Mux(pc == len(words) - 1, 0, pc + 1))
        m.d.sync += pc.eq(pc_next)
        rom_data = _rom(m, layout, words, pc_next, ~stall)
        # Two instruction registers: ``fetched`` (the memory and step-angle ROM are read for
        # it), then ``exe`` (it executes, with the read data registered).
        fetched = Signal(layout)
        exe = Signal(layout)
        # Before ``started`` ``fetched`` keeps its reset value, a no-op: an enable, not a mux.
        with m.If(~stall):
            m.d.sync += exe.eq(fetched)
        with m.If(~stall & started):
            m.d.sync += fetched.eq(rom_data)
        return pc, rom_data, fetched, exe

    def _memories(self, m, fetch, stall):
        """The data memory and the step-angle ROM, read for the fetched instruction and
        registered: (the memory word, the step angle, the memory's write port)."""
        prog, w = self.prog, self.widths
        mem_shape = signed(w.mem)
        # The program never reads a word in the clock it is written (``read_write_clash``), so
        # synthesis need not emulate the old word on a collision (no_rw_check: a bypass register
        # and mux per bit otherwise); the step-angle table is a block RAM, not LUTs.
        m.submodules.mem = mem = Memory(shape=mem_shape, depth=len(prog.mem_init), init=prog.mem_init,
                                        attrs={"no_rw_check": 1})
        mem_rd = mem.read_port(transparent_for=())
        mem_wr = mem.write_port()
        m.submodules.atan = atan = Memory(shape=signed(w.z), depth=len(prog.atan), init=prog.atan,
                                          attrs={"rom_style": "block"})
        atan_rd = atan.read_port()
        mem_q = Signal(mem_shape, name="mem_q")
        step = Signal(signed(w.z), name="step")
        m.d.comb += [mem_rd.addr.eq(fetch.rd), mem_rd.en.eq(~stall),
                     atan_rd.addr.eq(fetch.ci), atan_rd.en.eq(~stall)]
        with m.If(~stall):
            m.d.sync += [mem_q.eq(mem_rd.data), step.eq(atan_rd.data)]
        return mem_q, step, mem_wr

    def _decode(self, m, pre, stall):
        """Decoded controls registered beside ``exe`` (from ``pre``: the fetched instruction)."""
        # Controls of the wide datapaths decoded a clock early, from registers (their fan-out
        # to 80-bit muxes and adders was the slowest path).
        alu_op, bsel = pre.alu, pre.bsel

        def alu_is(*ops):
            return Cat(*(alu_op == op for op in ops)).any()

        adding = alu_is(*X.ADDING)
        decoded = {
            "sub": alu_is(X.A_SUB, X.A_NEG, X.A_CMPGT, X.A_CMPLT),
            "carry": alu_is(X.A_SUB, X.A_NEG, X.A_CMPLT),
            "left_zero": alu_is(X.A_NEG, X.A_MLD),
            # The adder's right operand (one-hot): the product, or one of ADDER_SOURCES.
            "right_product": alu_is(X.A_MLD, X.A_MACC),
            "right_acc": alu_is(X.A_NEG) | (adding & (bsel == X.B_ACC)),
            "right_mem": adding & (bsel == X.B_MEM),
            "right_root": adding & (bsel == X.B_ROOT),
            "cmp": alu_is(X.A_CMPGT, X.A_CMPLT), "gt": alu_is(X.A_CMPGT),
            "acc_total": alu_is(X.A_ADD, X.A_SUB, X.A_NEG, X.A_MLD, X.A_MACC),
            "acc_cond": alu_is(X.A_LD, X.A_ADD, X.A_SUB, X.A_NEG, X.A_MLD, X.A_MACC, *X.SHIFTS),
            "sat": alu_is(X.A_SATI, X.A_SATW),
            **{f"bus{source.value}": bsel == source for source in X.BusSource},
        }
        cop = pre.cop
        quarter = (cop == X.K_COARSE) | (cop == X.K_QROT)
        decoded.update(quarter=quarter, vectoring=(cop == X.K_VEC) | (cop == X.K_COARSE))
        # The micro-rotation's shift amount (0 for the quarter turns) drives two barrel shifters:
        # a register for each (the y shifter's holds the complement: not merged with x's).
        shift_x = Signal(range(len(self.prog.atan)), name="cordic_shift_x")
        shift_y_n = Signal(range(len(self.prog.atan)), name="cordic_shift_y_n")
        with m.If(~stall):
            m.d.sync += [shift_x.eq(Mux(quarter, 0, pre.ci)), shift_y_n.eq(~Mux(quarter, 0, pre.ci))]
        shift = (shift_x, ~shift_y_n)
        dec = {name: Signal(name=f"dec_{name}") for name in decoded}
        with m.If(~stall):
            m.d.sync += [dec[name].eq(value) for name, value in decoded.items()]
        return dec, shift

    def _ports(self, m, ins, pre, stall, io, acc, regs, run, w, pose_regs):
        """The word ports and the flags word (``io``: in_take, in_ready, out_valid)."""
        status = ins.io == X.IO_STATUS
        in_take, in_ready, out_valid = io
        state = Cat(pose_regs.of("status", ins.ip), pose_regs.of("tag", ins.ip)) if pose_regs else \
            Cat(regs["status"], regs["tag"])
        m.d.comb += [self.in_index.eq(Mux(stall, ins.iw, pre.iw)), self.in_take.eq(in_take),
                     self.in_ready.eq(in_ready),
                     self.out_valid.eq(out_valid), self.out_index.eq(Mux(status, 5, ins.iw)),
                     self.out_data.eq(Mux(status, state, acc[:w.word]))]
        if pose_regs:
            pose_regs.flags(m, ins, run, self.in_data, w.tag)
            return
        with m.If(run & (ins.io == X.IO_FLAGS)):
            m.d.sync += [regs["roll"].eq(self.in_data[0]), regs["back"].eq(self.in_data[1]),
                         regs["down"].eq(self.in_data[2])]
            if w.tag:
                m.d.sync += regs["tag"].eq(self.in_data[3:3 + w.tag])

def _rom(m, layout, words, addr, en):
    """The instruction ROM; deeper than 1,024 words (a program of two poses), in 9-bit slices,
    each one ECP5 block RAM deep (2,048 x 9): Yosys mapped a 72-bit word 1,121 deep to 512 x 36
    RAMs three deep with a 3:1 select per bit in LUTs (140 LUT4). Returns the word read."""
    if len(words) <= 1024:
        m.submodules.rom = rom = Memory(shape=layout, depth=len(words), init=words)
        rom_rd = rom.read_port()
        m.d.comb += [rom_rd.addr.eq(addr), rom_rd.en.eq(en)]
        return rom_rd.data
    bits = [Const.cast(word).value for word in words]
    slice_bits = 9
    parts = []
    for index, lsb in enumerate(range(0, layout.size, slice_bits)):
        width = min(slice_bits, layout.size - lsb)
        rom = Memory(shape=unsigned(width), depth=len(words), init=[(b >> lsb) & ((1 << width) - 1) for b in bits])
        m.submodules[f"rom{index}"] = rom
        port = rom.read_port()
        m.d.comb += [port.addr.eq(addr), port.en.eq(en)]
        parts.append(port.data)
    return layout(Cat(*parts))


def check_wide(wide_product):
    if not isinstance(wide_product, bool):
        raise ValueError(f"wide_product must be True or False, got {wide_product!r}")


def check_dsp(dsp) -> Dsp:
    """The compact core's multiplier mapping: generic, or ECP5 ``MULT18X18D`` primitives."""
    if dsp not in (Dsp.GENERIC, Dsp.ECP5):
        raise ValueError(f"dsp must be one of {Dsp.GENERIC}, {Dsp.ECP5}, got {dsp!r}")
    return Dsp(dsp)


def _check_poses(poses):
    if isinstance(poses, bool) or poses not in POSES:
        raise ValueError(f"poses must be one of {POSES}, got {poses!r}")


def check_tag(tag_width, limit):
    if isinstance(tag_width, bool) or not isinstance(tag_width, int) or not 0 <= tag_width <= limit:
        raise ValueError(f"tag_width must be an integer in [0, {limit}], got {tag_width!r}")


class SequencedIKCore(wiring.Component):
    """The IK core (payloads of :class:`~ik5r.hdl.pipelined.core.IKCore`) on the sequenced engine.

    Function: ``model.ik_solve`` bit for bit (q1..q5, status, tag), formats as ``IKCore``.
    Latency: ``latency`` clocks from an input transfer into an idle core to its result on ``o``
    (the program's length + 2 for one pose a program). Throughput: ``poses`` poses per program
    length, ``cycles_per_result`` clocks a pose: the next pose is taken into the input register
    while one is computed, and a result waits in the output register (the engine waits at an
    output word while a result is held). ``poses`` 2: a program computes two poses on the shared
    units (:func:`.program.interleave`); the second is skipped when no pose is there for it, so
    a pose never waits for another; on a cyclic program (:mod:`.modulo`) the first too, while
    the other is in flight. Nothing is lost, duplicated or reordered under back-pressure.
    ``dsp`` ecp5: the engine's limb multiplier on ``MULT18X18D`` primitives (:class:`SeqEngine`).
    """

    def __init__(self, *, constants: Constants, tag_width: int = 0, wide_product: bool = False,
                 poses: int = 1, dsp: str = Dsp.GENERIC):
        check_tag(tag_width, 26)
        check_wide(wide_product)
        _check_poses(poses)
        self._engine = e = SeqEngine(constants=constants, tag_width=tag_width, wide_product=wide_product,
                                     poses=poses, dsp=dsp)
        self.constants, self.arch, self.tag_width = constants, CoreArch.COMPACT, tag_width
        in_fields, out_fields = tagged_fields(constants, tag_width)
        self.in_fields, self.out_fields = in_fields, out_fields
        self.cycles_per_result = e.cycles if poses == 1 else e.cycles / poses
        # The first pose's status word (the program's last instruction for one pose), a clock
        # to the output register, two from an input transfer to the engine's first word.
        self.latency = e.first_status + 3
        # Input register, the program's poses, output register: a result waiting in the output
        # register while a program holds both its poses and the next pose is taken in.
        self.capacity = 2 + poses
        self.options = ({"wide_product": True} if wide_product else {}) | ({"poses": poses} if poses > 1 else {}) \
            | ({"dsp": e.dsp} if e.dsp != Dsp.GENERIC else {})
        super().__init__({
            "i": In(stream.Signature(data.StructLayout({n: s for n, (s, _, _) in in_fields.items()}))),
            "o": Out(stream.Signature(data.StructLayout({n: s for n, (s, _, _) in out_fields.items()}))),
        })

    def elaborate(self, platform):
        m = Module()
        m.submodules.engine = e = self._engine
        w = e.widths
        held = Signal(self.i.payload.shape())
        full = Signal()
        # Taken once the engine has booted, so the latency from any input transfer is `latency`.
        m.d.comb += self.i.ready.eq(~full & e.booted)
        with m.If(self.i.valid & self.i.ready):
            m.d.sync += [held.eq(self.i.payload), full.eq(1)]
        with m.If(e.in_take & (e.in_index == len(INPUT_WORDS))):
            m.d.sync += full.eq(0)
        flags = Cat(*(getattr(held, field) for field in FLAG_FIELDS.values()),
                    held.tag if self.tag_width else Const(0, 0))
        words = [Value.cast(getattr(held, WORD_FIELDS[name])).as_unsigned()
                 for name in INPUT_WORDS] + [flags]
        # The word the engine executes next, registered (off the engine's critical paths); valid
        # a clock after the input register is.
        in_q = Signal(e.in_bits)
        full_q = Signal()
        m.d.sync += [in_q.eq(select(words, e.in_index)), full_q.eq(full)]
        m.d.comb += [e.in_valid.eq(full_q), e.in_data.eq(in_q)]

        out = Signal(self.o.payload.shape())
        valid = Signal()
        m.d.comb += [self.o.payload.eq(out), self.o.valid.eq(valid), e.out_ready.eq(~valid)]
        with m.If(e.out_valid & ~valid):
            for j in range(5):
                with m.If(e.out_index == j):
                    m.d.sync += getattr(out, f"q{j + 1}").eq(e.out_data[:w.word])
            with m.If(e.out_index == 5):
                m.d.sync += [out.status.eq(e.out_data[:e.status_bits]), valid.eq(1)]
                if self.tag_width:
                    m.d.sync += out.tag.eq(e.out_data[e.status_bits:e.status_bits + self.tag_width])
        with m.If(valid & self.o.ready):
            m.d.sync += valid.eq(0)
        return m
