"""The status bits of the traced IK, kept beside the graph: :class:`Status` (what the body ORs
together) and :class:`StatusEvents` (its leaves, each on the value that decides it, for the cores).

A leaf is an event (a saturating node's or a rotation's flag, a :class:`~.nodes.Compare` of a
value with a constant, the zero vector of an atan2, or a :class:`~.nodes.Not` of a compare), the
status bit it sets and the branch flags that gate it. The cores read the events from
:class:`StatusEvents`, which :func:`~.trace.trace` returns with the graph; the graph's nodes do
not hold them.
"""

from __future__ import annotations

from dataclasses import dataclass

from .inputs import BranchFlag
from .nodes import AnyOf, Compare, Flag, Node, Not, Zero

__all__ = ["Status", "StatusEvent", "StatusEvents"]


@dataclass(frozen=True, slots=True)
class Status:
    """Status bits: a set of (event, bit, gates) leaves, ORed (the engine's sticky status);
    ``gates`` are (:class:`~.inputs.BranchFlag`, level) pairs, level 0 meaning the flag is set."""
    leaves: tuple = ()

    def __or__(self, other):
        if isinstance(other, int) and other == 0:
            return self
        return Status(self.leaves + other.leaves)

    __ror__ = __or__

    def gated(self, flag: Flag):
        return Status(tuple((ev, bit, gates + ((flag.flag, 0),)) for ev, bit, gates in self.leaves))

    def flat(self):
        """The leaves with every :class:`~.nodes.AnyOf` spread into its conditions, depth first."""
        def spread(event, bit, gates):
            if isinstance(event, AnyOf):
                for cond in event.conds:
                    yield from spread(cond, bit, gates)
            else:
                yield event, bit, gates

        for event, bit, gates in self.leaves:
            yield from spread(event, bit, gates)


@dataclass(frozen=True, slots=True)
class StatusEvent:
    """One status leaf: ``event`` sets ``bit`` where every flag of ``gates`` has its level.

    ``carrier`` is the value whose computation decides it (the saturating node or rotation, the
    compared value, the atan2), ``None`` for a :class:`~.nodes.Not` (a condition of its own)."""
    event: object
    bit: int
    gates: tuple[tuple[BranchFlag, int], ...]

    @property
    def carrier(self):
        if isinstance(self.event, Node):
            return self.event
        if isinstance(self.event, Compare):
            return self.event.value
        if isinstance(self.event, Zero):
            return self.event.atan2
        if isinstance(self.event, Not):
            return None
        raise NotImplementedError(f"status of {self.event!r}")


class StatusEvents:
    """The status leaves of one trace, in the order the body set them, and by carrier."""

    def __init__(self, status: Status):
        self.leaves = tuple(StatusEvent(event, bit, tuple(gates)) for event, bit, gates in status.flat())
        self._by_carrier: dict = {}
        for leaf in self.leaves:
            self._by_carrier.setdefault(leaf.carrier, []).append(leaf)

    def __iter__(self):
        return iter(self.leaves)

    def on(self, value) -> list:
        """The leaves ``value``'s computation decides, in order."""
        return list(self._by_carrier.get(value, ()))

    def saturation(self, node):
        """(bit, gates) of the flag of a saturating node or rotation (the last leaf on it), or
        None: the engine raises it with the ``SAT`` or the rotation's own flag."""
        own = [leaf for leaf in self.on(node) if leaf.event is node]
        return (own[-1].bit, own[-1].gates) if own else None

    def compares(self, value) -> list:
        """The :class:`~.nodes.Compare` leaves on ``value``."""
        return [leaf for leaf in self.on(value) if isinstance(leaf.event, Compare)]

    def zeros(self, atan2) -> list:
        """The zero-vector leaves of ``atan2``."""
        return [leaf for leaf in self.on(atan2) if isinstance(leaf.event, Zero)]
