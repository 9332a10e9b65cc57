"""Values a datapath needs many stages after it computes them, not carried through every
pipeline register: a delay element of the datapath itself. :meth:`~.stages.Datapath.stash` is a
stage taking keys out of the state (a :class:`Stashed` handle), :meth:`~.stages.Datapath.unstash`
a later stage bringing (some of) them back from that handle; both are zero-latency stages of the
stage list, so the distance is the register stages between them. The pipelined build
(:func:`build_stash`) makes each (from, to) stage pair one delay line stepping every clock, as the
pipeline: a register chain for short distances, else a RAM ring buffer with write and read
counters of its own. A key taken that its handle does not hold, taken twice, or never taken
fails when the datapath is made, naming the key.

Nothing here keeps state between builds: the values in a stash during one walk of the stages
(the construction check's, or an elaboration's) live in that walk's own :class:`Stashes`.
"""

from __future__ import annotations

from amaranth.hdl import Cat, Module, Signal, Value, unsigned
from amaranth.lib.memory import Memory

from ik5r.core.modes import Dsp

from .ecp5 import dp16kd_delay

__all__ = ["REGISTER_DELAY_MAX", "Stashed", "Stashes", "build_stash", "delay_line"]

#: Stash distances up to this many stages use a register chain instead of a RAM ring buffer.
REGISTER_DELAY_MAX = 4


class Stashed:
    """The keys one :meth:`~.stages.Datapath.stash` took out of the state, and which of them are
    still to be taken back (bookkeeping of the datapath's construction)."""

    def __init__(self, keys):
        self.keys = tuple(keys)
        self.pending = list(self.keys)

    def claim(self, keys) -> tuple:
        keys = tuple(keys) or tuple(self.pending)
        for key in keys:
            if key not in self.keys:
                raise ValueError(f"stash: {key!r} was not stashed here (stashed: {list(self.keys)})")
            if key not in self.pending:
                raise ValueError(f"stash: {key!r} taken twice")
            self.pending.remove(key)
        return keys


class Stashes:
    """The stash of one walk of a datapath's stages: the values each handle holds and where
    (register stages so far) they were put, and the links taken back, ``(key, value, origin,
    where, dst)``. ``take(key, value) -> value``: what an unstash puts in the state (the build's
    delay line output, or the value itself for the construction check)."""

    def __init__(self, take=lambda key, value: value):
        self.held, self.links, self.take = {}, [], take

    def put(self, handle: Stashed, state, where: int):
        if handle in self.held:
            raise ValueError(f"stash of {handle.keys[0]!r}: stashed twice in one walk")
        self.held[handle] = ({key: state[key] for key in handle.keys}, where)

    def get(self, handle: Stashed, keys, where: int) -> dict:
        if handle not in self.held:
            raise ValueError(f"unstash of {keys[0]!r} before its stash (or from another datapath)")
        values, origin = self.held[handle]
        if where - origin < 1:
            raise ValueError(f"stash of {keys[0]!r}: zero distance")
        out = {}
        for key in keys:
            value = Value.cast(values.pop(key))
            out[key] = self.take(key, value)
            self.links.append((key, value, origin, where, out[key]))
        return out

    def check_empty(self):
        left = sorted(key for values, _ in self.held.values() for key in values)
        if left:
            raise ValueError(f"stashed but never taken back: {left}")


def build_stash(m: Module, links, dsp: str = Dsp.GENERIC) -> None:
    """Drive each link's ``dst`` from its ``value`` delayed by ``where - origin`` cycles, one
    delay line per (origin, where) pair carrying its links side by side (pipelined build);
    ``dsp="ecp5"``: the RAM ring buffers are ``DP16KD`` primitives read through their output
    register (:func:`~.ecp5.dp16kd_delay`)."""
    groups = {}
    for link in links:
        groups.setdefault((link[2], link[3]), []).append(link)
    for (origin, where), group in sorted(groups.items()):
        word = Cat(*(link[1] for link in group))
        if dsp == Dsp.ECP5 and where - origin > REGISTER_DELAY_MAX:
            out = dp16kd_delay(m, f"stash_{origin}_{where}", word, where - origin)
        else:
            out = delay_line(m, word, origin, where)
        lsb = 0
        for _, value, _, _, dst in group:
            part = out[lsb:lsb + len(value)]
            m.d.comb += dst.eq(part.as_signed() if value.shape().signed else part)
            lsb += len(value)


def delay_line(m: Module, word, origin: int, where: int):
    """``word`` (put after register stage ``origin``) as it was ``where - origin`` clocks ago:
    registers, or a RAM ring buffer and its output register."""
    distance = where - origin
    if distance <= REGISTER_DELAY_MAX:
        for step in range(distance):
            reg = Signal(len(word), name=f"stash_{origin}_{where}_d{step}", reset_less=True)
            m.d.sync += reg.eq(word)
            word = reg
        return word
    depth = 1 << (distance - 1).bit_length()
    bits = (depth - 1).bit_length()
    mem = Memory(shape=unsigned(len(word)), depth=depth, init=[])
    m.submodules[f"stash_{origin}_{where}"] = mem
    wp = mem.write_port()
    rp = mem.read_port(transparent_for=())
    # Write and read addresses are counters of their own next to each RAM, stepped every clock
    # (the read one distance - 2 behind, then a register): one address counter shared by all
    # the RAMs, and a subtractor per RAM, made the slowest path.
    write_ptr = Signal(unsigned(bits), name=f"stash_{origin}_{where}_wptr")
    read_ptr = Signal(unsigned(bits), name=f"stash_{origin}_{where}_rptr",
                      init=-(distance - 2) % depth)
    m.d.sync += [write_ptr.eq(write_ptr + 1), read_ptr.eq(read_ptr + 1)]
    m.d.comb += [
        wp.addr.eq(write_ptr), wp.data.eq(word), wp.en.eq(1),
        rp.addr.eq(read_ptr),
    ]
    # The read data is registered before its user (an adder, often): an ECP5 block RAM's
    # clock-to-output without its output register is over 4 ns, near half of a 100 MHz cycle.
    out = Signal(len(word), name=f"stash_{origin}_{where}_q", reset_less=True)
    m.d.sync += out.eq(rp.data)
    return out
