"""Values a datapath needs many stages after it computes them, not carried through every
pipeline register: :meth:`Stash.put` takes them out of the state and returns a :class:`Stashed`
handle, :meth:`Stash.take` brings (some of) them back from that handle. ``pipelined``: a delay
line stepping every clock, as the pipeline (a register chain for short distances, else a RAM
ring buffer with write and read counters of its own, one per (from, to) stage pair); ``compact``
(one item in flight): the stage register itself, which holds its value until the next item
reaches it. A key taken that its handle does not hold, taken twice, or never taken fails when
the datapath is made, naming the key.
"""

from __future__ import annotations

from amaranth.hdl import Cat, Module, Signal, Value, unsigned
from amaranth.lib.memory import Memory

from ..modes import Arch
from .stages import Datapath
from .expr import drop

__all__ = ["Stash", "Stashed"]

#: Stash distances up to this many stages use a register chain instead of a RAM ring buffer.
REGISTER_DELAY_MAX = 4


class Stashed:
    """The keys one :meth:`Stash.put` took out of the state (after register stage ``where``),
    and which of them are still to be taken back."""

    def __init__(self, keys, where: int):
        self.keys, self.where = tuple(keys), where
        self.pending = list(keys)

    def claim(self, keys) -> tuple:
        keys = tuple(keys) or tuple(self.pending)
        for key in keys:
            if key not in self.keys:
                raise ValueError(f"stash: {key!r} was not stashed here (stashed: {list(self.keys)})")
            if key not in self.pending:
                raise ValueError(f"stash: {key!r} taken twice")
            self.pending.remove(key)
        return keys


class Stash:
    """The stash of one datapath (see the module docstring); :meth:`elaborate` drives the
    taken values after each build."""

    def __init__(self):
        self.handles = []
        self.reset()

    def reset(self):
        """Forget the values of the previous build (the construction check's, or an elaboration)."""
        self.stashed = {}
        self.links = []

    def put(self, dp: Datapath, *keys) -> Stashed:
        """A wiring stage taking ``keys`` out of the state; their handle."""
        handle = Stashed(keys, dp.latency)
        self.handles.append(handle)

        def fn(s):
            for key in keys:
                self.stashed[key] = (s[key], handle.where)
            return drop(s, *keys)
        dp.add_wiring(fn)
        return handle

    def take(self, dp: Datapath, handle: Stashed, *keys):
        """A wiring stage bringing ``keys`` (all that are left, if none given) of ``handle`` back."""
        keys, where = handle.claim(keys), dp.latency
        if where - handle.where < 1:
            raise ValueError(f"stash of {keys[0]!r}: zero distance")

        def fn(s):
            out = dict(s)
            for key in keys:
                value, origin = self.stashed.pop(key)
                value = Value.cast(value)
                dst = Signal(value.shape(), name=f"stash_{key}")
                self.links.append((key, value, origin, where, dst))
                out[key] = dst
            return out
        dp.add_wiring(fn)

    def check_taken(self):
        """Every stashed key taken back (when the datapath is complete)."""
        left = [key for handle in self.handles for key in handle.pending]
        if left:
            raise ValueError(f"stashed but never taken back: {left}")

    def elaborate(self, m: Module, arch: str):
        """Drive the unstashed signals (after ``Datapath.build``)."""
        if self.stashed:
            raise ValueError(f"stashed but never used: {sorted(self.stashed)}")
        if arch != Arch.PIPELINED:
            # One item in flight: the source register holds its value until the next item.
            for _, value, _, _, dst in self.links:
                m.d.comb += dst.eq(value)
            return
        groups = {}
        for link in self.links:
            groups.setdefault((link[2], link[3]), []).append(link)
        for (origin, where), links in sorted(groups.items()):
            distance = where - origin
            word = Cat(*(link[1] for link in links))
            if distance <= REGISTER_DELAY_MAX:
                for step in range(distance):
                    reg = Signal(len(word), name=f"stash_{origin}_{where}_d{step}", reset_less=True)
                    m.d.sync += reg.eq(word)
                    word = reg
                out = word
            else:
                depth = 1 << (distance - 1).bit_length()
                bits = (depth - 1).bit_length()
                mem = Memory(shape=unsigned(len(word)), depth=depth, init=[])
                m.submodules[f"stash_{origin}_{where}"] = mem
                wp = mem.write_port()
                rp = mem.read_port(transparent_for=())
                # Write and read addresses are counters of their own next to each RAM, stepped
                # every clock (the read one distance - 2 behind, then a register): one address
                # counter shared by all the RAMs, and a subtractor per RAM, made the slowest path.
                write_ptr = Signal(unsigned(bits), name=f"stash_{origin}_{where}_wptr")
                read_ptr = Signal(unsigned(bits), name=f"stash_{origin}_{where}_rptr",
                                  init=-(distance - 2) % depth)
                m.d.sync += [write_ptr.eq(write_ptr + 1), read_ptr.eq(read_ptr + 1)]
                m.d.comb += [
                    wp.addr.eq(write_ptr), wp.data.eq(word), wp.en.eq(1),
                    rp.addr.eq(read_ptr),
                ]
                # The read data is registered before its user (an adder, often): an ECP5 block
                # RAM's clock-to-output without its output register is over 4 ns, near half of
                # a 100 MHz cycle.
                out = Signal(len(word), name=f"stash_{origin}_{where}_q", reset_less=True)
                m.d.sync += out.eq(rp.data)
            lsb = 0
            for _, value, _, _, dst in links:
                part = out[lsb:lsb + len(value)]
                m.d.comb += dst.eq(part.as_signed() if value.shape().signed else part)
                lsb += len(value)

