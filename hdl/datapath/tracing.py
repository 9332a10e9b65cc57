"""The construction check of :meth:`ik5r.hdl.datapath.stages.Datapath.check`: the stages run once
on signals, through a state that records which keys each stage reads (:class:`Traced`) and who
produced each value (:class:`TraceState`), so a value read before it exists, or produced and
never read, is named with its stage when the datapath is built, not when the Verilog misbehaves.
"""

from __future__ import annotations

from amaranth.hdl import Signal, Value

from .stash import Stashes


class MissingValue(LookupError):
    """A stage read a key the state does not hold."""

    def __init__(self, key):
        super().__init__(key)
        self.key = key


class Traced(dict):
    """A state seen by :meth:`Datapath.check`: records the (outer) names of the keys read."""

    def __init__(self, values, reads: set, names: dict | None = None):
        super().__init__(values)
        self.reads = reads
        self.names = names or {}

    def __getitem__(self, key):
        name = self.names.get(key, key)
        if not dict.__contains__(self, key):
            raise MissingValue(name)
        self.reads.add(name)
        return dict.__getitem__(self, key)

    def get(self, key, default=None):
        return self[key] if key in self else default

    def derive(self, values: dict) -> "Traced":
        """A new state (e.g. :func:`~ik5r.hdl.datapath.expr.drop` of this one) recording into the same log."""
        return Traced(values, self.reads, self.names)


def traced_view(state, names: dict):
    """``{inner: state[outer]}`` for ``names`` (inner -> outer) without reading the values; a
    traced state's view records reads under the outer names (for stage wrappers)."""
    values = {inner: dict.__getitem__(state, outer) for inner, outer in names.items()}
    if isinstance(state, Traced):
        return Traced(values, state.reads, {inner: state.names.get(outer, outer)
                                             for inner, outer in names.items()})
    return values


def retraced(new: dict, old: dict) -> dict:
    """``new`` (a stage's result) traced like ``old`` (its input), for the next composed function."""
    if isinstance(old, Traced) and not isinstance(new, Traced):
        return old.derive(new)
    return new



class TraceState:
    """The values of a trace, who produced each and whether it has been read."""

    def __init__(self, name, values):
        self.name, self.values = name, values
        self.producer = {key: "the inputs" for key in values}
        self.used = {key: False for key in values}

    def read(self, reads):
        for key in reads:
            self.used[key] = True

    def _unread(self, key, by):
        raise ValueError(f"{self.name}: {key!r} produced by stage {self.producer[key]!r} is never "
                         f"read ({by} drops or replaces it)")

    def advance(self, out: dict, stage_name: str):
        """Take a stage's result; each value it produced becomes a fresh signal of its shape
        (as a register does: a trace through hundreds of stages must not build one expression)."""
        for key, value in self.values.items():
            if (key not in out or out[key] is not value) and not self.used[key]:
                self._unread(key, f"stage {stage_name!r}")
        for key, value in out.items():
            if key not in self.values or self.values[key] is not value:
                self.producer[key], self.used[key] = stage_name, False
                out[key] = Signal(Value.cast(value).shape(), name=f"trace_{key}")
        self.values = out

    def consume_all(self, by):
        for key in self.values:
            if not self.used[key]:
                raise ValueError(f"{self.name}: {key!r} produced by stage {self.producer[key]!r} "
                                 f"is never read (not an output)")


def trace_stages(name: str, stages, values: dict) -> TraceState:
    """Run ``stages`` (:class:`~ik5r.hdl.datapath.stages.Stage` s) once on ``values``, recording
    who produced and who read each value; raises ValueError naming the key and the stage."""
    state, stashes, latency = TraceState(name, values), Stashes(), 0
    for stage in stages:
        for step in range(max(stage.count, 1) if stage.iterated else 1):
            reads = set()
            traced = Traced(state.values, reads)
            try:
                out = (stage.fn(traced, step) if stage.iterated else
                       stage.wire(traced, stashes, latency) if stage.count == 0 else stage.fn(traced))
            except MissingValue as error:
                raise ValueError(f"{name}: stage {stage.name!r} reads {error.key!r}, which no "
                                 f"earlier stage produces") from None
            state.read(reads)
            state.advance(dict(out), stage.name)
            if stage.iterated:
                # An iterated stage's values feed its next step (the iterative build's feedback):
                # the last step's values of the keys it reads count as read (e.g. the y of a
                # vectoring CORDIC, driven to 0 and not used after).
                state.read(reads & set(out))
        latency += stage.count
    stashes.check_empty()
    return state
