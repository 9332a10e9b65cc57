"""The stash RAM that carries the IK core's tag is a delay line: the lemma, and its use.

The pipelined IK core's tag leaves the state after stage ``origin - 1`` (``select``) and comes
back ``distance`` stages later through a stash RAM ring buffer (:mod:`~ik5r.hdl.datapath.stash`; q18:
from stage 1 to stage 203, 202 cycles, a 256-entry RAM), written every clock at a write
pointer, read every clock ``distance - 2`` entries behind it, the read data registered twice.
The order induction of :mod:`.pipelined` cannot see inside a RAM, and a shadow of all its
entries (as the output FIFO once had) relates nothing to the stages' valid bits. So the proof is
compositional:

1. **The lemma** (:class:`StashLemma`, its own k-induction on the real
   :func:`~ik5r.hdl.datapath.stash.build_stash` code with the core's ``origin``, ``where`` and word
   width): for every cycle ``t0``, if no reset occurs in the cycles ``t0 .. t0 + distance - 1``,
   the stash's output at ``t0 + distance`` is the word written at ``t0``. The word is a free
   input (any value every cycle), the RAM is the real one (mapped to flip-flops, nothing cut),
   and the watched cycle ``t0`` is free. Inductive with: the read pointer is ``distance - 2``
   behind the write pointer, and the watched word is in the RAM entry ``age`` behind the write
   pointer (read through an extra combinational read port the harness adds), then in the read
   port's register, then in the output register.

2. **Its use** (:func:`stash_tags`): in the core's order job the RAM is cut (its read data are
   free values) and a *ghost delay line* ``g`` of ``distance`` registers follows the word
   written (``g[e]`` is the word of ``e + 1`` cycles ago: the tag of the item now in stage
   ``origin + e``), and the harness assumes (``Assume``) that the stash's output equals
   ``g[distance - 1]`` whenever stage ``where - 1`` (the one reading it) holds an item. That is
   the lemma's conclusion: an item in stage ``where - 1`` at ``t`` entered stage 0 at
   ``t - (where - 1)``, and every stage valid bit is cleared by a reset
   (:func:`~ik5r.hdl.datapath.build.build_pipelined`: ``<stage>_valid`` is the previous stage's of the
   cycle before, reset by ``rst``), so no reset occurred in ``t - where .. t - 1``, which
   contains the lemma's premise window ``t - distance .. t - 1`` (``origin`` >= 1). This step
   (the valid chain implies no reset in the window) is argued, not machine-checked.

With the ghost registers as the stages' tags, :func:`.pipelined.track_marks` asserts where the
marks are through the whole delay line, as for a block without a stash.
"""

from __future__ import annotations

import os

from amaranth.hdl import Assert, Assume, Elaboratable, Module, ResetSignal, Signal

from ..datapath.stash import REGISTER_DELAY_MAX, build_stash

__all__ = ["StashLemma", "tag_links", "stash_tags"]


def tag_links(dut, inner, find) -> list:
    """The stash spans of ``dut`` (a pipelined build, ``inner`` its elaborated module) that carry
    the tag: (origin, where, lsb of the tag in the RAM word, width of the word). The keys of a
    span share its word in the order they are taken back; their widths are those of the
    signals the unstash drives (``stash_<key>``)."""
    groups = {}
    for origin, where, keys in dut._dp.stash_spans():
        groups.setdefault((origin, where), []).extend(keys)
    found = []
    for (origin, where), keys in sorted(groups.items()):
        if "tag" in keys:
            widths = [len(find(inner, f"stash_{key}")) for key in keys]
            found.append((origin, where, sum(widths[:keys.index("tag")]), sum(widths)))
    return found


class StashLemma(Elaboratable):
    """The stash RAM of ``distance = where - origin`` stages (``width``-bit words) is a delay
    line of ``distance`` cycles (module docstring). ``skew`` (the self-test) makes the ghost
    believe the distance is ``distance + skew``: the proof must then fail."""

    def __init__(self, origin: int, where: int, width: int, skew: int = 0):
        if where - origin <= REGISTER_DELAY_MAX:
            raise ValueError(f"stash {origin}->{where}: a register chain, not a RAM")
        self.origin, self.where, self.width, self.skew = origin, where, width, skew
        self.word = Signal(width, name="env_word")
        self.watch = Signal(name="env_watch")
        #: (file name, line) of each assertion -> its name (how SymbiYosys names a failed one).
        self.assert_names = {}

    def _assert(self, test, name: str):
        check = Assert(test, name, src_loc_at=1)
        self.assert_names[(os.path.basename(check.src_loc[0]), check.src_loc[1])] = name
        return check

    @property
    def ports(self):
        return [self.word, self.watch]

    def elaborate(self, platform):
        m = Module()
        origin, where = self.origin, self.where
        out = Signal(self.width, name="stash_out")
        # The real stash code on one link of the core's origin, where and word width.
        build_stash(m, [("word", self.word, origin, where, out)])
        name = f"stash_{origin}_{where}"
        mem = m._named_submodules[name][0]
        wptr = rptr = None
        for signal in m._driving:
            wptr = signal if signal.name == f"{name}_wptr" else wptr
            rptr = signal if signal.name == f"{name}_rptr" else rptr
        port = mem.read_ports[0]
        distance, depth = where - origin, mem.depth
        claimed = distance + self.skew
        # The watched word: written at t0 (a free choice), ``age`` cycles ago.
        watching = Signal(name="watching")
        age = Signal(range(claimed + 1), name="watch_age")
        value = Signal(self.width, name="watch_value")
        with m.If(ResetSignal()):
            m.d.sync += watching.eq(0)
        with m.Elif(watching & (age < claimed)):
            m.d.sync += age.eq(age + 1)
        with m.Elif(self.watch):
            m.d.sync += [watching.eq(1), age.eq(1), value.eq(self.word)]
        with m.Else():
            m.d.sync += watching.eq(0)
        # An extra read port (the harness's, not the core's) to state where the word is.
        peek = mem.read_port(domain="comb")
        m.d.comb += peek.addr.eq(wptr - age)
        m.d.comb += self._assert(rptr == (wptr - (distance - 2)) % depth, "stash_pointers")
        with m.If(watching):
            m.d.comb += self._assert((age >= 1) & (age <= claimed), "stash_age")
            with m.If(age <= distance - 2):
                m.d.comb += self._assert(peek.data == value, "stash_entry")
            with m.If(age == distance - 1):
                m.d.comb += self._assert(port.data == value, "stash_read")
            with m.If(age == claimed):
                m.d.comb += self._assert(out == value, "stash_delay")
        return m


def stash_tags(m, dut, inner, stages, find) -> list:
    """``stages`` ((valid, tag or None) per register stage) with the stages the tag skips (in
    a stash RAM) given the ghost delay line's registers as tags, and the ``Assume`` tying the
    stash's output to the line (module docstring). Returns the completed list."""
    stages = list(stages)
    for origin, where, lsb, _ in tag_links(dut, inner, find):
        distance = where - origin
        source = stages[origin - 1][1]
        width = len(source)
        line = [Signal(width, name=f"ghost_tag_{origin}_{where}_{e}", reset_less=True)
                for e in range(distance)]
        m.d.sync += line[0].eq(source)
        m.d.sync += [line[e].eq(line[e - 1]) for e in range(1, distance)]
        for e in range(distance):
            valid, tag = stages[origin + e]
            if tag is not None:
                raise ValueError(f"stage {origin + e} has a tag register inside the stash span")
            stages[origin + e] = (valid, line[e])
        q = find(inner, f"stash_{origin}_{where}_q")
        with m.If(stages[where - 1][0]):
            m.d.comb += Assume(q[lsb:lsb + width] == line[-1])
    if any(tag is None for _, tag in stages):
        raise ValueError("a register stage without a tag register outside the stash spans")
    return stages
