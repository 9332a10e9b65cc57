"""The IR of the traced IK (:mod:`.trace`): hash-consed nodes and the conditions over them.

A :class:`Node` is one operation (:class:`~.ops.Op`) on argument nodes (or integers) with
parameters, and an interval bound of its value (``lo``, ``hi``, by the operation's
:class:`~.registry.OpSpec`); :class:`Graph` keeps the nodes of one trace, the same operation on
the same operands being one node. :class:`Sop` is an exact sum of products, :class:`Cond` and its
kinds the conditions a selection or a status bit reads (the status leaves: :mod:`.status`).
Nodes, sums and conditions are frozen: a core keeps what it derives from them in maps of its
own, keyed by the object. They compare by identity (hash-consing makes a node unique in its
graph; a node's ``==`` records a condition, as the body's words do).
"""

from __future__ import annotations

from dataclasses import dataclass

from ik5r.core.fxconfig import Constants

from .inputs import BranchFlag
from .ops import Op
from .registry import SPECS


def bits_of(lo: int, hi: int) -> int:
    """Signed bits holding every integer in [lo, hi]."""
    return max((-lo - 1).bit_length() if lo < 0 else 0, hi.bit_length() if hi > 0 else 0) + 1


class Graph:
    """The nodes of one trace, hash-consed (the graph grows while the body is traced; its nodes
    do not change)."""

    def __init__(self, k: Constants):
        self.k, self.ki = k, k.internal
        self.guard = k.cfg.internal_guard_bits
        self.nodes: list = []
        self._table: dict = {}
        self._outputs: dict = {}

    def node(self, op: Op, args=(), params=(), cls=None):
        """The node of ``op`` on ``args`` (nodes or integers) with ``params``: the existing one
        if there is one; its bound by the operation's :class:`~.registry.OpSpec`."""
        spec = SPECS[op]
        if len(args) != spec.arity or len(params) != len(spec.params):
            raise TypeError(f"{op.name} takes {spec.arity} arguments and parameters {spec.params}")
        # Keyed by the arguments' ids in the graph (a node's == records a condition; an integer
        # argument is a 1-tuple, apart from every id).
        key = (op, tuple((a,) if isinstance(a, int) else a.id for a in args), params)
        if key in self._table:
            return self._table[key]
        bound = spec.bound(self, args, params) if spec.bound else self.word_range(self.ki.cfg.width)
        n = (cls or Node)(self, op, tuple(args), params, *bound, len(self.nodes))
        self._table[key] = n
        self.nodes.append(n)
        if op in (Op.ROTX, Op.ROTY):
            self._outputs.setdefault(args[0], {})["y" if op == Op.ROTY else "x"] = n
        return n

    def sop(self, terms, const: int) -> "Sop":
        """A new exact sum (not hash-consed: each is formed where the body forms it)."""
        s = Sop(self, tuple(terms), int(const), -1 - len(self.nodes))
        self.nodes.append(s)
        return s

    def outputs_of(self, rotation) -> dict:
        """The x and y nodes the body took of ``rotation``: {"x": node, "y": node}, in the order
        they were traced."""
        return dict(self._outputs.get(rotation, {}))

    def word_range(self, bits: int):
        return -(1 << (bits - 1)), (1 << (bits - 1)) - 1


@dataclass(frozen=True, eq=False, repr=False, slots=True)
class Node:
    """A value of the traced IK (a word the engine can hold in its accumulator and memory)."""
    g: Graph
    op: Op
    args: tuple
    params: tuple
    lo: int
    hi: int
    id: int

    @property
    def exact(self) -> bool:
        """The value is an exact product's (a clip of an exact sum, a sum or difference with
        one): wider than a word, as the vocabulary's exact words hold it."""
        return self.op in _EXACT_OPS and any(getattr(v, "exact", False) for v in self.args)

    def bounds(self) -> tuple[int, int]:
        return self.lo, self.hi

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
        return self.g.node(Op.NEG, (self,))

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

    __hash__ = object.__hash__


@dataclass(frozen=True, eq=False, repr=False, slots=True)
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


@dataclass(frozen=True, eq=False, repr=False, slots=True)
class Check(Node):
    """The check word of a value (its top bits: a multiplier operand only)."""

    def __mul__(self, other):
        return self.g.sop([(self, other, False, 0)], 0)

    def __lshift__(self, n: int):
        return self.g.sop([(self, 1, False, n)], 0)


#: The operations whose value is exact when an argument's is.
_EXACT_OPS = (Op.CLIP, Op.ADD, Op.SUB)


def add(g, a, b):
    if isinstance(a, int):
        a, b = b, a
    if isinstance(b, int) and b == 0:
        return a
    return g.node(Op.ADD, (a, b))


def sub(g, a, b):
    if isinstance(b, int) and b == 0:
        return a
    # c - (c - x) is x (1 - (1 - c3), the cosine an acos of complements gets back).
    if (isinstance(a, int) and getattr(b, "op", None) == Op.SUB and isinstance(b.args[0], int)
            and b.args[0] == a):
        return b.args[1]
    return g.node(Op.SUB, (a, b))


@dataclass(frozen=True, eq=False, repr=False, slots=True)
class Sop:
    """An exact sum of products (and a constant): the accumulator's wide values, which never go
    to memory. Terms: (a, b, negative, shift) for ±(a * b) << shift."""
    g: Graph
    terms: tuple
    const: int
    id: int

    #: An exact sum, wider than a word.
    exact = True

    def __repr__(self):
        return f"<sop#{self.id}>"

    def _terms(self, other):
        if isinstance(other, Node):
            raise NotImplementedError("an exact sum plus a word (add to a constant only)")
        return (other.terms, other.const) if isinstance(other, Sop) else ((), int(other))

    def __add__(self, other):
        terms, const = self._terms(other)
        return self.g.sop(self.terms + terms, self.const + const)

    def __sub__(self, other):
        terms, const = self._terms(other)
        return self.g.sop(self.terms + tuple((a, b, not neg, s) for a, b, neg, s in terms),
                          self.const - const)

    def __neg__(self):
        return self.g.sop([(a, b, not neg, s) for a, b, neg, s in self.terms], -self.const)

    def __gt__(self, c):
        return compare(self, ">", c)

    def __lt__(self, c):
        return compare(self, "<", c)

    @property
    def of_check_words(self) -> bool:
        """A sum of products of check words (an orientation check): plain integers, narrow."""
        return any(isinstance(v, Check) for a, b, _, _ in self.terms for v in (a, b))

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
    if isinstance(v, Check):
        inner = v.args[0]
        return inner.lo >> v.g.ki.check_shift, inner.hi >> v.g.ki.check_shift
    return (v,) if isinstance(v, int) else (v.lo, v.hi)


# --- conditions ----------------------------------------------------------------------------------


class Cond:
    """A condition: a comparison of a value with a constant, a branch flag, a CORDIC zero vector."""

    __slots__ = ()

    def __or__(self, other):
        return AnyOf((self, other))

    def __bool__(self):
        raise TypeError("the traced IK branches on a symbolic condition (use fx.select)")


@dataclass(frozen=True, eq=False, slots=True)
class Compare(Cond):
    value: object
    op: str
    const: int


@dataclass(frozen=True, eq=False, slots=True)
class Not(Cond):
    cond: Cond


@dataclass(frozen=True, eq=False, slots=True)
class Flag(Cond):
    """A branch flag of the pose (:class:`~.inputs.BranchFlag`)."""
    flag: BranchFlag


@dataclass(frozen=True, eq=False, slots=True)
class Zero(Cond):
    """The zero vector of an atan2 (the engine's CORDIC zero latch)."""
    atan2: Node


@dataclass(frozen=True, eq=False, slots=True)
class AnyOf(Cond):
    conds: tuple


def compare(value, op, const):
    if not isinstance(const, int):
        raise NotImplementedError("comparisons against constants only")
    return Compare(value, op, int(const))
