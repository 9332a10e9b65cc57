"""A pose's registers in an engine whose program runs several poses (:func:`.program.interleave`).

Each pose of the program has its own flags (roll, back, down), tag and status bits, and, after
the first, a ``live`` bit: the pose's first input word is taken if the core has one and skipped
otherwise (the pose runs on as a bubble: its words are not taken, its results not offered, its
words in memory its own), so that a pose in flight never waits for the next one. The first pose
of the program waits for its input as a one-pose program does: an idle engine waits there. An
instruction's pose fields (:data:`.isa.POSE_FIELDS`) say whose registers it acts on.
"""

from __future__ import annotations

from amaranth.hdl import Cat, Const, Mux, Signal

from . import isa as X
from ..datapath.expr import select

__all__ = ["PoseRegisters"]


class PoseRegisters:
    """The registers of each pose (pose 0: the engine's own ``regs``), and the selects of the
    executing instruction's poses."""

    def __init__(self, regs: dict, poses: int, w, cyclic: bool = False):
        self.poses, self.cyclic = poses, cyclic
        self.each = [{name: regs[name] for name in ("back", "down", "roll", "status", "tag")}]
        for p in range(1, poses):
            self.each.append({
                "back": Signal(name=f"back_p{p}"), "down": Signal(name=f"down_p{p}"),
                "roll": Signal(name=f"roll_p{p}"), "status": Signal(w.status, name=f"status_p{p}"),
                "tag": Signal(max(1, w.tag), name=f"tag_p{p}")})
        self.live = ([Signal(name="live_p0")] if cyclic else [Const(1, 1)]) + [
            Signal(name=f"live_p{p}") for p in range(1, poses)]

    def of(self, name: str, pose) -> "Value":
        """Register ``name`` of the pose ``pose`` (an instruction's pose field)."""
        return select([r[name] for r in self.each], pose)

    def ports(self, m, ins, in_valid, out_ready, run):
        """(stall, in_take, in_ready, out_valid) of the word ports; a later pose's first word
        decides whether the pose is live. In a cyclic program (:mod:`.modulo`) the first pose's
        too, where another pose is in flight (live until its status word): the engine waits
        there only when none is."""
        reading = (ins.io == X.IO_IN) | (ins.io == X.IO_FLAGS)
        writing = (ins.io == X.IO_OUT) | (ins.io == X.IO_STATUS)
        live = Signal(name="io_live")
        start = Signal(name="io_pose_start")
        first = (ins.io == X.IO_IN) & (ins.iw == 0)
        m.d.comb += [live.eq(select(self.live, ins.ip)),
                     start.eq(first if self.cyclic else first & (ins.ip != 0))]
        stall = (reading & ~in_valid & live & ~start) | (writing & ~out_ready & live)
        if self.cyclic:
            in_flight = Signal(name="io_in_flight")
            m.d.comb += in_flight.eq(Cat(*self.live).any())
            stall |= start & ~in_valid & ~in_flight
            for p in range(self.poses):
                with m.If(run & (ins.io == X.IO_STATUS) & (ins.ip == p)):
                    m.d.sync += self.live[p].eq(0)
        for p in range(0 if self.cyclic else 1, self.poses):
            with m.If(run & start & (ins.ip == p)):
                m.d.sync += self.live[p].eq(in_valid)
        # Taken: a word that is there, of a live pose (the engine waits for it) or a later pose's
        # first. (Mux(start, in_valid, live) is the same where it matters; Yosys maps this form
        # to fewer LUTs: the commit that chose it has the figures.)
        take = reading & run & in_valid & (live | start)
        return stall, take, reading & (live | start), writing & live

    def flags(self, m, ins, run, in_data, tag_bits: int):
        """The flags word into its pose's registers."""
        for p, r in enumerate(self.each):
            with m.If(run & (ins.io == X.IO_FLAGS) & (ins.ip == p)):
                m.d.sync += [r["roll"].eq(in_data[0]), r["back"].eq(in_data[1]), r["down"].eq(in_data[2])]
                if tag_bits:
                    m.d.sync += r["tag"].eq(in_data[3:3 + tag_bits])

    def status(self, m, ins, pending):
        """Each pose's status bits: a pending event ORed into its pose's a clock after the event
        (``pending`` registered with the instruction's ``sp``), cleared by the pose's flags."""
        pending_pose = Signal(range(self.poses), name="status_pending_pose")
        m.d.sync += pending_pose.eq(ins.sp)
        for p, r in enumerate(self.each):
            clear = (ins.io == X.IO_FLAGS) & (ins.ip == p)
            m.d.sync += r["status"].eq(Mux(clear, 0, r["status"] | Mux(pending_pose == p, pending, 0)))
