"""The pipelined IK core's datapath generated from the traced IK: the same graph of
:func:`ik5r.core.ik.solve` (:func:`~ik5r.hdl.graph.trace.trace`) the compact core's program is
lowered from, so the IK is described once.

Every value of the graph needed by a joint or a status bit gets a unit (:mod:`.ik_units`);
the units are scheduled as soon as their operands are ready (ASAP, latency per unit) and the
datapath's stage ``t`` runs every unit step of clock ``t`` side by side. The state after a stage
holds only the values still to be read (the datapath registers what the state holds); a value
that waits longer than :data:`~ik5r.hdl.datapath.stash.REGISTER_DELAY_MAX` stages for its next reader
travels in a stash of the datapath instead. The status bits are ORed into one word,
``st``, in the stage each becomes known; the branch flags gate theirs.
"""

from __future__ import annotations

from collections import defaultdict

from amaranth.hdl import Const, Mux

from ik5r.core.fxconfig import Constants
from ik5r.core.status import FIXED_WIDTH

from ..graph.ops import Op
from ..blocks.chains import retraced
from ..datapath.stages import Datapath
from ..datapath.expr import drop
from .glue import unit_of
from .units import Ctx, Derived
from ..graph.inputs import BranchFlag
from ..graph.nodes import Flag, Node, Sop
from ..graph.status import StatusEvents
from ..graph.trace import trace
from ..datapath.stash import REGISTER_DELAY_MAX

__all__ = ["graph_datapath", "STATUS_BITS"]

STATUS_BITS = FIXED_WIDTH
#: The state keys of the branch flags.
FLAG_KEYS = tuple(flag.value for flag in BranchFlag)


class _Keys:
    """The state key of each value object (an input's is its field's)."""

    def __init__(self):
        self.names: dict = {}

    def __call__(self, v) -> str:
        if isinstance(v, Flag):
            return v.flag.value
        if isinstance(v, Node) and v.op == Op.INPUT:
            return v.params[0]
        if v not in self.names:
            if isinstance(v, Derived):
                name = f"{v.kind}_{self(v.node)}"
            elif isinstance(v, (Node, Sop)):
                name = f"{v.op}{len(self.names)}" if isinstance(v, Node) else f"sop{len(self.names)}"
            else:
                name = f"cond{len(self.names)}"
            self.names[v] = name
        return self.names[v]


def _is_input(v) -> bool:
    return isinstance(v, Flag) or (isinstance(v, Node) and v.op == Op.INPUT)


def _leaves(ctx, events: StatusEvents) -> list:
    """The status leaves as (bit value object, status bit, gate flag keys): a saturation's or a
    rotation's flag, a compare (or its negation), an atan2's zero vector."""
    out = []
    for leaf in events:
        if any(level != 0 for _, level in leaf.gates):
            raise NotImplementedError("a status bit gated by a flag being low")
        gates = tuple(flag.value for flag, _ in leaf.gates)
        event = leaf.event            # (StatusEvents has refused any other kind of event)
        out.append((ctx.derived("flag", event) if isinstance(event, Node) else ctx.canon(event),
                    leaf.bit, gates))
    return out


class _Schedule:
    """The units of the values the joints and status need, in dependency order, and when each
    starts and each value is ready (ASAP)."""

    def __init__(self, ctx, roots):
        self.ctx = ctx
        self.units, self.unit_of, self.ready = [], {}, {}
        self.start = {}
        self.end = 0
        for root in roots:
            self._need(root)
        for unit in self.units:
            start = max((self.ready[r] for r in unit.reads), default=0)
            self.start[unit] = start
            for w in unit.writes:
                self.ready[w] = start + unit.latency
            self.end = max(self.end, start + unit.latency)

    def _producer(self, v):
        if isinstance(v, Derived):
            return v.node
        if isinstance(v, Node) and v.op in (Op.ROTX, Op.ROTY):
            return v.args[0]
        return v

    def _need(self, v):
        v = self.ctx.canon(v)
        if isinstance(v, int) or v in self.ctx.needed:
            return
        self.ctx.needed.add(v)
        if _is_input(v):
            self.ready[v] = 0
            return
        producer = self._producer(v)
        if producer in self.unit_of:
            return
        unit = unit_of(self.ctx, f"u{len(self.unit_of)}", producer)
        self.unit_of[producer] = unit
        for r in unit.reads:
            self._need(r)
        self.units.append(unit)


def graph_datapath(words: Constants, tag: bool, adders) -> Datapath:
    """The IK on the internal format (the inputs arrive shifted up, :meth:`IKCore._inputs`; the
    joints leave rounded back to words): ``j1`` .. ``j5``, ``st`` (and ``tag``), the units side
    by side."""
    joints, events, _ = trace(words)
    keys = _Keys()
    ctx = Ctx(words.internal, adders, keys)
    leaves = _leaves(ctx, events)
    gates = {flag.value: Flag(flag) for flag in BranchFlag}
    sched = _Schedule(ctx, list(joints) + [v for v, _, _ in leaves] + list(gates.values()))
    # When each value is read: by units (at their start), the status word, the outputs.
    uses = defaultdict(list)
    for unit in sched.units:
        for r in unit.reads:
            uses[keys(ctx.canon(r))].append(sched.start[unit])
    ready = {keys(v): sched.ready[v] for v in map(ctx.canon, _values(sched, gates))}
    leaf_at = defaultdict(list)
    for v, bit, gate_keys in leaves:
        leaf_at[ready[keys(v)]].append((keys(v), bit, gate_keys))
    end = max([ready[keys(j)] for j in joints] + list(leaf_at) + [1])
    for t, items in leaf_at.items():
        for key, _, gate_keys in items:
            for k in (key, *gate_keys):
                uses[k].append(t)
    for j in joints:
        uses[keys(j)].append(end)
    if tag:
        # The tag is registered in stage 0, then waits in the stash: the formal order proof
        # follows it from a tag register into the stash (hdl/formal/stash.py).
        ready["tag"] = 0
        uses["tag"] += [0, end]
    return _assemble(sched, keys, ready, uses, leaf_at, joints, end)


def _values(sched, gates):
    for unit in sched.units:
        yield from unit.writes
    yield from gates.values()
    for unit in sched.units:
        yield from (r for r in unit.reads if _is_input(r))


def _stash_segments(ready, uses, wired):
    """(put at, take at, key) for each wait longer than a register chain: from a value's ready
    time to its first reader, and from one reader to the next."""
    segments = []
    for key, times in uses.items():
        times = sorted(set(times))
        if times[0] < ready[key]:
            raise AssertionError(f"{key} read at {times[0]}, ready at {ready[key]}")
        # A wiring unit's value exists in the stage of its start: it can be put after it.
        first = ready[key] + (key in wired and times[0] > ready[key])
        points = [(first, times[0])] + [(a + 1, b) for a, b in zip(times, times[1:])]
        segments += [(put, take, key) for put, take in points if take - put > REGISTER_DELAY_MAX]
    return segments


#: A value waits in registers up to this many bit-cycles to be put in the stash later, with the
#: values of a group (one RAM, its two pointers and output register) taken back at the same stage.
SHARE_BITS = 64


def _grouped(segments, width) -> list:
    """``segments`` with puts moved later, to a group taken at the same stage, where that costs
    few registers (:data:`SHARE_BITS`)."""
    out, puts_of = [], defaultdict(list)
    for put, take, key in sorted(segments, key=lambda seg: (seg[1], -seg[0])):
        later = [p for p in puts_of[take]
                 if p >= put and (p - put) * width(key) <= SHARE_BITS and take - p > REGISTER_DELAY_MAX]
        if later:
            put = min(later)
        else:
            puts_of[take].append(put)
        out.append((put, take, key))
    return out


def _assemble(sched, keys, ready, uses, leaf_at, joints, end) -> Datapath:
    """The datapath: stage t runs the unit steps of clock t, ORs the status bits known at t and
    drops the values read for the last time; the stash's put and take wiring between stages."""
    dp = Datapath("ik", adders=sched.ctx.adders)
    active, wiring = defaultdict(list), defaultdict(list)
    for unit in sched.units:
        dp.declare(**unit.shapes)
        start = sched.start[unit]
        if unit.wiring:
            wiring[start].append(unit)
        for j, step in enumerate([] if unit.wiring else unit.steps):
            active[start + j].append(step)
    last = defaultdict(list)
    for key, times in uses.items():
        if max(times) < end:
            last[max(times)].append(key)
    puts = defaultdict(list)
    wired = {keys(w) for unit in sched.units if unit.wiring for w in unit.writes}
    word = sched.ctx.ki.cfg.width + 1

    def width(key):
        """A value's width (an input word's, a flag's one bit; undeclared: about a word)."""
        return 1 if key in FLAG_KEYS else dp.shapes[key].width if key in dp.shapes else word
    for put, take, key in _grouped(_stash_segments(ready, uses, wired), width):
        puts[put, take].append(key)
    handles = {}
    for t in range(end + 1):
        for (put, take), keys_ in sorted(puts.items()):
            if take == t:
                dp.unstash(handles.pop((put, take)))
        for (put, take), keys_ in sorted(puts.items()):
            if put == t:
                handles[put, take] = dp.stash(*keys_)
        fns = [u.steps[0] for u in wiring[t]] + ([] if t == end else active[t])
        fns.append(_status_fn(leaf_at[t]))
        if t < end:
            dp.add(f"t{t}", _stage_fn(fns, last[t]))
        else:
            dp.add_wiring(_stage_fn(fns, [], outputs=[keys(j) for j in joints]))
    return dp


def _stage_fn(fns, dead, outputs=None):
    def run(s):
        for fn in fns:
            s = retraced(fn(s), s)
        if outputs is None:
            return drop(s, *(key for key in dead if key in s))
        out = {f"j{i + 1}": s[key] for i, key in enumerate(outputs)}
        out["st"] = s["st"]
        if "tag" in s:
            out["tag"] = s["tag"]
        return retraced(out, s)
    return run


def _status_fn(items):
    """The status word with the bits known now ORed in (each gated by its branch flags)."""
    def run(s):
        if not items:
            return s
        # STATUS_BITS, or 7 where OUT_OF_LIMITS is among the bits (an arm with limits only).
        width = max([STATUS_BITS] + [bit.bit_length() for _, bit, _ in items])
        st = s["st"] if "st" in s else Const(0, STATUS_BITS)
        for key, bit, gate_keys in items:
            cond = s[key]
            for g in gate_keys:
                cond = cond & s[g]
            st = st | Mux(cond, Const(bit, width), Const(0, width))
        return dict(s, st=st)
    return run
