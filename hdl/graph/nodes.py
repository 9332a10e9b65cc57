"""The IR of the traced IK (:mod:`.trace`): hash-consed nodes and the conditions and status
events over them.

A :class:`Node` is one operation (:class:`~.ops.Op`) on argument nodes (or integers) with
parameters, and an interval bound of its value (``lo``, ``hi``); :class:`Graph` keeps the nodes of
one trace, the same operation on the same operands being one node. :class:`Sop` is an exact sum
of products, :class:`Cond` and its kinds the conditions a selection or a status bit reads,
:class:`Status` the status leaves of the solve. Both cores read the graph through these classes.
"""

from __future__ import annotations

from ik5r.core.fxconfig import Constants

from .inputs import BranchFlag
from .ops import Op


def bits_of(lo: int, hi: int) -> int:
    """Signed bits holding every integer in [lo, hi]."""
    return max((-lo - 1).bit_length() if lo < 0 else 0, hi.bit_length() if hi > 0 else 0) + 1


class Graph:
    """The nodes of one trace, hash-consed."""

    def __init__(self, k: Constants):
        self.k, self.ki = k, k.internal
        self.guard = k.cfg.internal_guard_bits
        self.nodes: list[Node] = []
        self._table: dict = {}

    def node(self, op: str, args=(), params=(), lo=None, hi=None, cls=None):
        key = (op, tuple(a if isinstance(a, int) else id(a) for a in args), params)
        if key in self._table:
            return self._table[key]
        n = (cls or Node)(self, op, tuple(args), params, lo, hi)
        self._table[key] = n
        self.nodes.append(n)
        return n

    def word_range(self, bits: int):
        return -(1 << (bits - 1)), (1 << (bits - 1)) - 1


class Node:
    """A value of the traced IK (a word the engine can hold in its accumulator and memory)."""

    __hash__ = object.__hash__

    def __init__(self, g: Graph, op, args, params, lo, hi):
        self.g, self.op, self.args, self.params = g, op, args, params
        self.id = len(g.nodes)
        self.lo, self.hi = (lo, hi) if lo is not None else g.word_range(g.ki.cfg.width)
        self.events: list = []       # status events of this value (see seq_lower.attach_status)
        self.stat = None             # (bit, gates) of a saturation's status

    @property
    def bits(self) -> int:
        return bits_of(self.lo, self.hi)

    def __repr__(self):
        return f"<{self.op}#{self.id}>"

    def __bool__(self):
        raise TypeError("the traced IK branches on a symbolic value (use fx.select)")

    # -- arithmetic: recorded --
    def __add__(self, other):
        return add(self.g, self, other)

    __radd__ = __add__

    def __sub__(self, other):
        return sub(self.g, self, other)

    def __rsub__(self, other):
        return sub(self.g, other, self)

    def __neg__(self):
        return self.g.node(Op.NEG, (self,), lo=-self.hi, hi=-self.lo)

    def __rshift__(self, n: int):
        if n != self.g.ki.check_shift:
            raise NotImplementedError(f"{self} >> {n}: only the check word shift is an engine word")
        return self.g.node(Op.CHECK, (self,), cls=Check)

    def __gt__(self, c):
        return compare(self, ">", c)

    def __lt__(self, c):
        return compare(self, "<", c)

    def __le__(self, c):
        return compare(self, "<", c + 1)

    def __ge__(self, c):
        return compare(self, ">", c - 1)

    def __eq__(self, c):
        if c != 0 or self.lo < 0:
            raise NotImplementedError("== only against 0 of a non-negative value")
        # sat(isqrt(r)) == 0 exactly when r == 0 (r >= 0; isqrt(r) >= 1 for r >= 1, saturation
        # keeps 0): the test needs the radicand only, not the root's digit steps.
        value = self
        while isinstance(value, Node) and value.op in (Op.SAT, Op.SQRT):
            value = value.args[0]
        return Not(compare(value, ">", 0))


class Input(Node):
    """An input word (word format); ``<< guard`` is the internal word the engine reads in, and
    ``>> check_shift`` of the word format its check word."""

    def __lshift__(self, n: int):
        if n != self.g.guard:
            raise NotImplementedError("an input word is shifted by the internal guard bits only")
        return self.g.node(Op.INPUT, (), (self.params[0],))

    def __rshift__(self, n: int):
        if n + self.g.guard != self.g.ki.check_shift:
            raise NotImplementedError(f"input word >> {n}: not its check word")
        return (self << self.g.guard) >> self.g.ki.check_shift


class Check(Node):
    """The check word of a value (its top bits: a multiplier operand only)."""

    def __mul__(self, other):
        return Sop(self.g, [(self, other, False, 0)], 0)

    def __lshift__(self, n: int):
        return Sop(self.g, [(self, 1, False, n)], 0)


def add(g, a, b):
    if isinstance(a, int):
        a, b = b, a
    if isinstance(b, int) and b == 0:
        return a
    blo, bhi = (b, b) if isinstance(b, int) else (b.lo, b.hi)
    return g.node(Op.ADD, (a, b), lo=a.lo + blo, hi=a.hi + bhi)


def sub(g, a, b):
    if isinstance(b, int) and b == 0:
        return a
    # c - (c - x) is x (1 - (1 - c3), the cosine an acos of complements gets back).
    if (isinstance(a, int) and getattr(b, "op", None) == Op.SUB and isinstance(b.args[0], int)
            and b.args[0] == a):
        return b.args[1]
    alo, ahi = (a, a) if isinstance(a, int) else (a.lo, a.hi)
    blo, bhi = (b, b) if isinstance(b, int) else (b.lo, b.hi)
    return g.node(Op.SUB, (a, b), lo=alo - bhi, hi=ahi - blo)


class Sop:
    """An exact sum of products (and a constant): the accumulator's wide values, which never go
    to memory. Terms: (a, b, negative, shift) for ±(a * b) << shift."""

    __hash__ = object.__hash__

    def __init__(self, g, terms, const):
        self.g, self.terms, self.const = g, list(terms), int(const)
        self.events: list = []
        self.id = -1 - len(g.nodes)
        g.nodes.append(self)

    def _terms(self, other):
        if isinstance(other, Node):
            raise NotImplementedError("an exact sum plus a word (add to a constant only)")
        return (other.terms, other.const) if isinstance(other, Sop) else ([], int(other))

    def __add__(self, other):
        terms, const = self._terms(other)
        return Sop(self.g, self.terms + terms, self.const + const)

    def __sub__(self, other):
        terms, const = self._terms(other)
        return Sop(self.g, self.terms + [(a, b, not neg, s) for a, b, neg, s in terms],
                   self.const - const)

    def __neg__(self):
        return Sop(self.g, [(a, b, not neg, s) for a, b, neg, s in self.terms], -self.const)

    def __gt__(self, c):
        return compare(self, ">", c)

    def __lt__(self, c):
        return compare(self, "<", c)

    def bounds(self):
        lo = hi = self.const
        for a, b, neg, s in self.terms:
            ends = [x * y << s for x in _ends(a) for y in _ends(b)]
            if a is b:            # a square: never negative
                ends = [max(ends), 0 if min(_ends(a)) <= 0 <= max(_ends(a)) else min(ends)]
            ends = [-e for e in ends] if neg else ends
            lo, hi = lo + min(ends), hi + max(ends)
        return lo, hi


def _ends(v):
    if isinstance(v, int):
        return (v,)
    if isinstance(v, Check):
        inner = v.args[0]
        return inner.lo >> v.g.ki.check_shift, inner.hi >> v.g.ki.check_shift
    return v.lo, v.hi


# --- conditions and status ------------------------------------------------------------------------


class Cond:
    """A condition: a comparison of a value with a constant, a branch flag, a CORDIC zero vector."""

    def __or__(self, other):
        return AnyOf(self, other)

    def __bool__(self):
        raise TypeError("the traced IK branches on a symbolic condition (use fx.select)")


class Compare(Cond):
    def __init__(self, value, op: str, const: int):
        self.value, self.op, self.const = value, op, int(const)


class Not(Cond):
    def __init__(self, cond):
        self.cond = cond


class Flag(Cond):
    """A branch flag of the pose (:class:`~.inputs.BranchFlag`)."""

    def __init__(self, flag: BranchFlag):
        self.flag = flag


class Zero(Cond):
    """The zero vector of an atan2 (the engine's CORDIC zero latch)."""

    def __init__(self, atan2):
        self.atan2 = atan2


class AnyOf(Cond):
    def __init__(self, *conds):
        self.conds = conds


def compare(value, op, const):
    if not isinstance(const, int):
        raise NotImplementedError("comparisons against constants only")
    return Compare(value, op, const)


class Status:
    """Status bits: a set of (event, bit, gates) leaves, ORed (the engine's sticky status)."""

    def __init__(self, leaves=()):
        self.leaves = tuple(leaves)

    def __or__(self, other):
        if isinstance(other, int) and other == 0:
            return self
        return Status(self.leaves + other.leaves)

    __ror__ = __or__

    def gated(self, flag: Flag):
        return Status((ev, bit, gates + ((flag.flag, 0),)) for ev, bit, gates in self.leaves)

    def flat(self):
        """The leaves with every :class:`AnyOf` spread into its conditions, depth first: (event,
        bit, gates), the event a saturating :class:`Node`, a :class:`Compare`, :class:`Not` or
        :class:`Zero`."""
        def spread(event, bit, gates):
            if isinstance(event, AnyOf):
                for cond in event.conds:
                    yield from spread(cond, bit, gates)
            else:
                yield event, bit, gates

        for event, bit, gates in self.leaves:
            yield from spread(event, bit, gates)


def rotation_outputs(r) -> dict:
    """The x and y nodes the body took of the rotation ``r``: {"x": node, "y": node}, in graph
    order."""
    return {node.op[-1]: node for node in r.g.nodes
            if isinstance(node, Node) and node.op in (Op.ROTX, Op.ROTY) and node.args[0] is r}


# --- the vocabulary -----------------------------------------------------------------------------
