"""The sequenced IK core (:class:`~ik5r.hdl.sequenced.engine.SequencedIKCore`) under the stream contract.

The engine has no :class:`~ik5r.hdl.datapath.stages.Datapath`; its control is the program counter, the
instruction ROM's read register and the two instruction registers (``fetched``, ``exe``), the
``started``/``booted`` bits and the core's input register (``full``, ``full_q``, ``in_q``) and
output register (``valid``, ``out``). The program has no branches: which instruction executes is
a function of the program counter alone, and only ``io`` instructions wait. So an item is:

* in the input register while ``full``;
* in the engine from the read of the last data word (the core then frees its input register; the
  flags word is already in ``in_q``) to the status word's write (index ``S``, the program's last
  instruction) included, i.e. while the executing instruction's index is in [F, S] (``F``: the
  flags word's read);
* in the output register while ``valid``.

:func:`sequencer` asserts the invariants that make this inductive (the ROM read data, ``fetched``
and ``exe`` are the program's words at pc, pc - 1 and pc - 2 in their word-port fields, the only
ones the control reads, ``in_q`` holds the flags word when
the flags read executes) and returns the occupancy (for the contract's ``conservation``) and the
tags of the three places (for the ``order`` group, proved by k-induction against a ghost queue
of the tags accepted and not yet taken). The data (memory, step-angle ROM) is cut by the
job's Yosys script; the arithmetic registers are the engine's, unconstrained in the induction.
"""

from __future__ import annotations

from dataclasses import dataclass

from amaranth.hdl import Array, Cat, Const, Module, Mux, Signal, Value
from amaranth.lib import data

from ..sequenced import isa as X

__all__ = ["DATA_REGISTERS", "POSE_DATA_REGISTERS", "Places", "elaborate_engine", "sequencer", "tag_queue"]

#: The instruction fields the control reads (the word ports; ``ip``: a program of two poses').
CONTROL_FIELDS = ("io", "iw", "ip")

#: The engine's data registers (arithmetic, CORDIC, multiplier, square root, condition flags,
#: status): the control never reads them, the job's Yosys script cuts them to free values.
DATA_REGISTERS = ("acc", "cx", "cy", "cz", "ma", "mb", "la", "lb", "prod", "rad", "root", "rem",
                  "mem_q", "step", "flag", "zero", "back", "down", "roll", "status")
#: The same registers of the second pose of a program of two (:mod:`..sequenced.poses`).
POSE_DATA_REGISTERS = ("back_p1", "down_p1", "roll_p1", "status_p1")


@dataclass
class Places:
    """Where the items inside the core are, as one-bit values, and their tags (the engine's: one
    per pose of its program, the first pose's first out)."""
    full: Value        # the input register holds one
    busy: list         # the engine holds pose p's
    valid: Value       # the output register holds one
    held_tag: Value
    engine_tags: list
    out_tag: Value

    @property
    def occupancy(self) -> Value:
        return self.full + sum(self.busy) + self.valid


def elaborate_engine(inner: Module, engine, platform) -> Module:
    """Elaborate the core's engine in place of the component in ``inner`` (so the harness can
    reach its registers: Amaranth would otherwise elaborate it later, into signals unseen)."""
    module = engine.elaborate(platform)
    engine._MustUse__silence = True
    _, src_loc = inner._named_submodules["engine"]
    inner._named_submodules["engine"] = (module, src_loc)
    return module


def _index(program, io, pose: int = 0) -> int:
    found = [j for j, ins in enumerate(program.code) if ins.io == io and (ins.ip or 0) == pose]
    if len(found) != 1:
        raise ValueError(f"the program must have one io={io} instruction of pose {pose}, has {len(found)}")
    return found[0]


def _control_rom(code):
    """``control(word)``: the control fields of an instruction word (a Value); ``rom``: those of
    the program's words, as constants. Only the word-port fields (io, iw) of an instruction reach
    the control and the tag path: comparing just them leaves the other fields to the data, which
    the job's script cuts."""
    layout = X.word_layout(code)
    fields = [name for name in CONTROL_FIELDS if name in layout.members]

    def control(word):
        view = data.View(layout, word)
        return Cat(Value.cast(getattr(view, name)) for name in fields)

    return control, Array(Const.cast(control(X.encode(layout, ins))) for ins in code)


def _rom_word(engine: Module) -> Value:
    """The instruction ROM's read data (its slices' in order, where the ROM is sliced)."""
    roms = sorted((name for name in engine._named_submodules if name.startswith("rom")),
                  key=lambda name: int(name[3:] or 0))
    return Cat(engine._named_submodules[name][0].read_ports[0].data for name in roms)


def _check_order(first: list, last: list, count: int):
    if not (all(f < s for f, s in zip(first, last)) and first == sorted(first) and last == sorted(last)
            and last[-1] == count - 1 and first[-1] + 2 < count):
        raise ValueError("the sequenced invariants expect each pose's flags read before its status "
                         "write, the poses in order, and the last status write ending the program")


def sequencer(m: Module, dut, inner: Module, engine: Module, find, check) -> Places:
    """Assert (``check(test, name)``) the engine's control invariants; return the places."""
    e = dut._engine
    count, poses = len(e.prog.code), e.poses
    first = [_index(e.prog, X.IO_FLAGS, p) for p in range(poses)]
    last = [_index(e.prog, X.IO_STATUS, p) for p in range(poses)]
    _check_order(first, last, count)
    control, rom = _control_rom(e.prog.code)
    pc, exe = e.trace["pc"], e.trace["exe"]
    started = find(engine, "started")
    fetched, exe = control(find(engine, "fetched")), control(exe)
    rom_data = control(_rom_word(engine))
    booted = e.booted
    lapped = Signal(name="seq_lapped")         # the program counter has wrapped since reset
    with m.If(booted & (pc == count - 1)):
        m.d.sync += lapped.eq(1)
    before = Mux(pc == 0, count - 1, pc - 1)
    before2 = Mux(pc == 0, count - 2, Mux(pc == 1, count - 1, pc - 2))
    executing = booted & (lapped | (pc >= 2))  # exe holds the instruction at index before2
    m.d.comb += [check(pc < count, "seq_pc"), check(booted | ~lapped, "seq_lapped")]
    with m.If(~started):
        m.d.comb += check(~booted & (pc == 0) & (fetched == 0) & (exe == 0), "seq_reset")
    with m.If(started & ~booted):
        m.d.comb += check((pc == 0) & (fetched == 0) & (exe == 0) & (rom_data == rom[0]), "seq_boot")
    with m.If(booted):
        m.d.comb += [
            check(rom_data == rom[pc], "seq_rom"),
            check(fetched == rom[before], "seq_fetched"),
            check(exe == Mux(executing, rom[before2], 0), "seq_exe"),
            check(lapped | (pc != 0), "seq_lapped"),
        ]
    full, full_q, valid = (find(inner, name) for name in ("full", "full_q", "valid"))
    held = data.View(dut.i.payload.shape(), find(inner, "held"))
    flags_tag = find(inner, "in_q")[3:3 + dut.tag_width]
    # A pose of the program after the first is in only if its first word was taken (``live``).
    live = [Const(1, 1)] + [find(engine, f"live_p{p}") for p in range(1, poses)]
    tags = [e.trace["tag"]] + [find(engine, f"tag_p{p}") for p in range(1, poses)]
    # The core frees its input register when the engine takes a pose's last data word (the next
    # word, the flags, is then in in_q): the flags read executes at pc = first + 2 from in_q,
    # with full_q still high and full low, and without waiting.
    at_flags = [Signal(name=f"seq_at_flags{p or ''}") for p in range(poses)]
    m.d.comb += [at_flags[p].eq(booted & (pc == first[p] + 2)) for p in range(poses)]
    taking = [at & alive for at, alive in zip(at_flags, live)]
    m.d.comb += check(~full_q | full | Cat(*taking).any(), "seq_input")
    for take in taking:
        with m.If(take):
            m.d.comb += check(full_q & ~full & (flags_tag == held.tag), "seq_flags_word")
    with m.If(~booted):
        m.d.comb += check(~full & ~full_q & ~valid, "seq_input")
    busy = [Signal(name=f"seq_busy{p or ''}") for p in range(poses)]
    m.d.comb += [busy[p].eq(executing & live[p] & (before2 >= first[p]) & (before2 <= last[p]))
                 for p in range(poses)]
    out = data.View(dut.o.payload.shape(), find(inner, "out"))
    engine_tags = [Mux(at, flags_tag, tag) for at, tag in zip(at_flags, tags)]
    return Places(full, busy, valid, held.tag, engine_tags, out.tag)


def tag_queue(m: Module, capacity: int, inside, taken_in, taken_out, i_tag, places: Places, check):
    """A ghost queue of the tags accepted and not taken (oldest first): the output register,
    the engine and the input register hold its entries in this order."""
    queue = Array(Signal(len(i_tag), name=f"queue_{j}") for j in range(capacity))
    with m.If(taken_out):
        m.d.sync += [queue[j].eq(queue[j + 1]) for j in range(capacity - 1)]
    with m.If(taken_in):
        m.d.sync += queue[inside - taken_out].eq(i_tag)
    with m.If(places.valid):
        m.d.comb += check(places.out_tag == queue[0], "order")
    # The engine's poses in program order: a program's first pose leaves before its second.
    position = places.valid
    for busy, tag in zip(places.busy, places.engine_tags):
        with m.If(busy):
            m.d.comb += check(tag == queue[position], "order_engine")
        position = position + busy
    with m.If(places.full):
        m.d.comb += check(places.held_tag == queue[position], "order_input")
