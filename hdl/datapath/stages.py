"""The datapath of the ik5r arithmetic blocks: a list of typed stages over named values.

Every block (:class:`~ik5r.hdl.blocks.cordic.Atan2`, :class:`~ik5r.hdl.blocks.cordic.Rotate`,
:class:`~ik5r.hdl.blocks.sqrt.Sqrt`, :class:`~ik5r.hdl.blocks.acos.Acos`, the IK core) describes its arithmetic
once, as a :class:`Datapath`: an ordered list of :class:`Stage` s, each a pure function from a
dictionary of named values (the state carried by one item) to the next such dictionary. The
same description is elaborated in one of two architectures (:mod:`.build`):

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
bit for bit; the widths are derived from :class:`~ik5r.core.fxconfig.Constants` with proofs of no
overflow in the comments of each block.

One option maps a datapath to the FPGA's primitives without changing a bit of its results:
``Datapath(adders=adders_for("ecp5"))`` built with ``dsp="ecp5"`` (pipelined): each partial
product is an ECP5 ``MULT18X18D`` whose input and output registers are the two pipeline
registers around it, and each ``dp.adders.add_sub`` (the CORDIC micro-rotations) is a ``CCU2C``
carry chain whose own LUTs take the direction. The mapping is the datapath's
:attr:`Datapath.adders`, passed explicitly to whatever builds its stage functions. (The small IK
core, ``compact``, is the sequenced engine of ``hdl.sequenced``, which has no datapath of
stages.)

Chains. A datapath doubles as a *chain* that another one composes (the IK core runs the
blocks' chains side by side): it declares its ``inputs`` and ``outputs`` and names split points
(:meth:`Datapath.mark`, :meth:`Datapath.part`), so a composer takes a named part of a block's
chain, never a slice of its stage list by name. :meth:`Datapath.check` traces the stages once
at construction: every value read was produced earlier, and every value produced is read or
is an output; a failure names the key and the stage.
"""

from __future__ import annotations

import contextlib
import contextvars
import enum
from dataclasses import dataclass, replace
from typing import Callable

from amaranth.hdl import Shape, Signal

from ik5r.core.modes import Arch

from .adders import Ecp5Adders, GenericAdders, adders_for   # noqa: F401 (cordic.py imports them here)
from .expr import drop
from .stash import Stashed, Stashes
from .tracing import MissingValue, Traced, retraced, trace_stages

__all__ = ["StageKind", "Stage", "GenericAdders", "Ecp5Adders", "adders_for",
           "Datapath", "OUTPUT_FIFO_LATENCY", "traced_view", "retraced", "steps_per_stage",
           "check_steps_per_stage"]

#: Cycles from the last stage of the pipelined architecture to the item on ``o``: the register
#: in front of the output FIFO, then the FIFO's (:class:`.output_fifo.CreditFifo`) RAM write and
#: its RAM read into the output register.
OUTPUT_FIFO_LATENCY = 3


class StageKind(enum.Enum):
    """What a stage is: registered (``fn(state)``, one register set), iterated (``fn(state, i)``,
    ``count`` repetitions), wiring (``fn(state)``, no register, zero latency), or the two ends
    of a stash (:mod:`.stash`, zero latency): ``stash`` takes its keys out of the state
    (``fn(state)``), ``unstash`` brings them back (``fn(state, values)``)."""
    REGISTERED = "registered"
    ITERATED = "iterated"
    WIRING = "wiring"
    STASH = "stash"
    UNSTASH = "unstash"


@dataclass(frozen=True)
class Stage:
    """One stage of a :class:`Datapath`. ``count``: its register stages (1 registered, n
    iterated, 0 wiring); ``stash`` and ``keys``: the handle and the keys of a stash or unstash
    stage."""
    name: str
    kind: StageKind
    fn: Callable
    count: int = 1
    stash: Stashed | None = None
    keys: tuple = ()

    def __post_init__(self):
        expected = {StageKind.REGISTERED: 1, StageKind.WIRING: 0, StageKind.STASH: 0,
                    StageKind.UNSTASH: 0}.get(self.kind)
        if expected is not None and self.count != expected:
            raise ValueError(f"stage {self.name!r}: a {self.kind.value} stage has count {expected}")
        if self.kind is StageKind.ITERATED and self.count < 1:
            raise ValueError(f"stage {self.name!r}: count must be at least 1, got {self.count}")

    @property
    def iterated(self) -> bool:
        return self.kind is StageKind.ITERATED

    def wire(self, state, stashes: Stashes, latency: int):
        """The state after this zero-latency stage, ``latency`` register stages into the
        datapath: a wiring stage's function, or a stash's end moving its keys into or out of
        ``stashes`` (the walk's own)."""
        if self.kind is StageKind.STASH:
            stashes.put(self.stash, state, latency)
        elif self.kind is StageKind.UNSTASH:
            return self.fn(state, stashes.get(self.stash, self.keys, latency))
        return self.fn(state)

    def with_fn(self, fn, *, name: str | None = None) -> "Stage":
        """The same kind and count with another function (and name)."""
        return replace(self, fn=fn, name=self.name if name is None else name)

    def __iter__(self):
        """``(name, fn, count, iterated)``: the tuple form ``hdl/formal`` reads."""
        return iter((self.name, self.fn, self.count, self.iterated))

    @staticmethod
    def of(item) -> "Stage":
        """A :class:`Stage`, or one from the tuple form ``(name, fn, count, iterated)``."""
        if isinstance(item, Stage):
            return item
        name, fn, count, iterated = item
        kind = (StageKind.ITERATED if iterated else
                StageKind.WIRING if count == 0 else StageKind.REGISTERED)
        return Stage(name, kind, fn, count)


# --- micro-steps per pipeline stage ------------------------------------------------------------

#: Micro-steps (CORDIC micro-rotations, square-root digits) per register stage of the datapaths
#: made while :func:`steps_per_stage` is active (1 outside it).
_STEPS_PER_STAGE = contextvars.ContextVar("ik5r_steps_per_stage", default=1)


def check_steps_per_stage(value, arch: str = Arch.PIPELINED) -> int:
    """``value`` if it is a valid count of micro-steps per stage for ``arch``, else raises:
    a positive int; more than 1 only in the pipelined architecture (the iterative one runs one
    step per clock on one register set)."""
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ValueError(f"steps per stage must be a positive integer, got {value!r}")
    if value != 1 and arch != Arch.PIPELINED:
        raise ValueError(f"{value} steps per stage apply to the pipelined architecture, not {arch!r}")
    return value


@contextlib.contextmanager
def steps_per_stage(count: int):
    """Every :class:`Datapath` made inside (a composer's chains, e.g. the IK core's units built
    by code that does not pass the option along) puts ``count`` micro-steps in one stage."""
    token = _STEPS_PER_STAGE.set(check_steps_per_stage(count))
    try:
        yield
    finally:
        _STEPS_PER_STAGE.reset(token)


def _grouped(fn, count: int, per_stage: int):
    """``fn(state, i)`` for ``i < count`` as ``ceil(count / per_stage)`` steps, step ``j``
    running ``i = j * per_stage ...`` one after the other in one clock (pipelined: ``j`` an
    int). The same expressions as one step per stage, so the same bits."""
    def run(s, j):
        if not isinstance(j, int):
            raise TypeError("micro-steps grouped per stage need the pipelined build (an int step)")
        for i in range(j * per_stage, min(count, (j + 1) * per_stage)):
            s = retraced(fn(s, i), s)
        return s
    run.grouped = True
    return run, -(-count // per_stage)


# --- the datapath ------------------------------------------------------------------------------

class Datapath:
    """An ordered list of :class:`Stage` s over named values; see the module docstring.

    ``add(name, fn)``: a registered stage, ``fn(state) -> state``.
    ``add_iter(name, fn, count)``: ``count`` repetitions of ``fn(state, i) -> state`` with ``i`` an
    int (pipelined, unrolled) or an unsigned Value (iterative, one step per clock).
    ``add_wiring(fn)``: a renaming with no register (zero latency; ``fn`` must be wiring only).
    ``stash(*keys)`` / ``unstash(handle)``: keys set aside for many stages, not carried through
    every register set (:mod:`.stash`).

    A stage's functions must be pure: they build expressions and never add statements. Values
    named by :meth:`declare` are stored in their declared shape (the blocks prove the values fit),
    others in the shape of their expression (never lossy). As a chain, ``inputs`` and
    ``outputs`` name the keys it reads from and leaves to its composer.
    """

    def __init__(self, name: str, *, adders=None, inputs=(), outputs=(), steps_per_stage: int | None = None):
        self.name = name
        #: What ``add_sub`` of this datapath's stages builds (:func:`adders_for`).
        self.adders = adders if adders is not None else GenericAdders()
        self.inputs, self.outputs = tuple(inputs), tuple(outputs)
        #: Micro-steps per register stage of :meth:`add_micro_steps` (the context's by default).
        self.steps_per_stage = check_steps_per_stage(
            _STEPS_PER_STAGE.get() if steps_per_stage is None else steps_per_stage)
        self.stages: list[Stage] = []
        self.shapes = {}
        #: Named split points: name -> index of the first stage after the mark.
        self.marks = {}

    def declare(self, **shapes):
        for key, shape in shapes.items():
            self.shapes[key] = Shape.cast(shape)

    def append(self, stage: Stage):
        self.stages.append(stage)

    def add(self, name, fn):
        self.append(Stage(name, StageKind.REGISTERED, fn))

    def add_iter(self, name, fn, count: int):
        self.append(Stage(name, StageKind.ITERATED, fn, count))

    def add_micro_steps(self, name, fn, count: int):
        """A block's micro-steps (CORDIC micro-rotations, square-root digits): ``count`` steps
        ``fn(state, i)``, :attr:`steps_per_stage` of them per register stage (the last one
        fewer)."""
        if self.steps_per_stage == 1:
            self.add_iter(name, fn, count)
            return
        self.add_iter(name, *_grouped(fn, count, self.steps_per_stage))

    def add_wiring(self, fn):
        self.append(Stage("wiring", StageKind.WIRING, fn, 0))

    def stash(self, *keys) -> Stashed:
        """A stage taking ``keys`` out of the state until an :meth:`unstash` of the returned
        handle brings them back, as many register stages later as lie between (:mod:`.stash`)."""
        handle = Stashed(keys)
        self.append(Stage("stash", StageKind.STASH, lambda s: drop(s, *handle.keys), 0,
                          stash=handle, keys=handle.keys))
        return handle

    def unstash(self, handle: Stashed, *keys):
        """A stage bringing ``keys`` (all that are left, if none given) of ``handle`` back."""
        keys = handle.claim(keys)
        self.append(Stage("unstash", StageKind.UNSTASH, lambda s, values: {**s, **values}, 0,
                          stash=handle, keys=keys))

    def stash_spans(self) -> list:
        """``(origin, where, keys)`` of each unstash, in stage order: the keys carried from
        register stage ``origin`` to ``where``."""
        spans, origin, latency = [], {}, 0
        for stage in map(Stage.of, self.stages):
            if stage.kind is StageKind.STASH:
                origin[stage.stash] = latency
            elif stage.kind is StageKind.UNSTASH:
                spans.append((origin[stage.stash], latency, stage.keys))
            latency += stage.count
        return spans

    def mark(self, name: str):
        """Name the split point after the stages added so far (see :meth:`part`)."""
        self.marks[name] = len(self.stages)

    def part(self, start: str | None = None, stop: str | None = None) -> "Datapath":
        """The stages from mark ``start`` (None: the first) up to mark ``stop`` (None: the last)
        as a chain of their own, with this datapath's shapes and adders."""
        def index(mark, default):
            if mark is None:
                return default
            if mark not in self.marks:
                raise KeyError(f"chain {self.name!r} has no split point {mark!r} "
                               f"(it has {sorted(self.marks)})")
            return self.marks[mark]
        lo, hi = index(start, 0), index(stop, len(self.stages))
        out = Datapath(f"{self.name}[{start}:{stop}]", adders=self.adders,
                       steps_per_stage=self.steps_per_stage)
        out.shapes = dict(self.shapes)
        out.stages = list(self.stages[lo:hi])
        out.marks = {name: at - lo for name, at in self.marks.items() if lo <= at <= hi}
        return out

    @property
    def latency(self) -> int:
        """Register stages of the datapath: cycles from an input transfer to the result in the
        last stage's registers."""
        return sum(Stage.of(stage).count for stage in self.stages)

    def stream_latency(self, arch: str) -> int:
        """Cycles from an input transfer to its result on ``o`` when ``o`` is not held: the
        stages, and in the pipelined architecture the output FIFO."""
        return self.latency + (OUTPUT_FIFO_LATENCY if arch == Arch.PIPELINED else 0)

    def capacity(self, arch: str) -> int:
        """Items the built block holds at most (accepted, not yet taken from ``o``); while ``o``
        is held it accepts this many, then ``i.ready`` stays low. Pipelined: the depth of the
        output FIFO, one more than a power of two at least the stream latency (the credit that
        lets an item in is registered, so one slot more than the items a full-rate stream keeps
        in flight; :class:`.output_fifo.CreditFifo` holds one item in its output register and the
        rest in a RAM, whose pointers then wrap for free). Iterative: one."""
        if arch != Arch.PIPELINED:
            return 1
        return (1 << (self.stream_latency(arch) - 1).bit_length()) + 1

    def check_chain(self, shape) -> None:
        """:meth:`check` as a chain: from its declared ``inputs`` (signals of ``shape``) to its
        declared ``outputs``."""
        inputs = {key: Signal(shape, name=f"check_{key}") for key in self.inputs}
        self.check(inputs, lambda s: {key: s[key] for key in self.outputs})

    def check(self, inputs: dict, outputs_of) -> None:
        """Trace the stages once on ``inputs`` (each iterated stage step by step, as pipelined):
        raise ValueError naming the key and the stage when a stage reads a value no earlier stage
        produced, or a value produced (or an input) is dropped, replaced or left at the end
        without being read; ``outputs_of(final_state)`` reads the outputs. An iterated stage's
        values count as read by its own next step."""
        tracing = getattr(self.adders, "tracing", None)
        if tracing is not None:
            self.adders.tracing = True
        try:
            state = trace_stages(self.name, map(Stage.of, self.stages), dict(inputs))
            reads = set()
            try:
                outputs_of(Traced(state.values, reads))
            except MissingValue as error:
                raise ValueError(f"{self.name}: the outputs read {error.key!r}, which no stage "
                                 f"produces") from None
            state.read(reads)
            state.consume_all("the outputs")
        finally:
            if tracing is not None:
                self.adders.tracing = tracing
