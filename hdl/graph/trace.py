"""The IK body (:func:`ik5r.core.ik.solve`) traced into a graph for the sequenced engine.

``ik.solve(fx, fw, ...)`` is written once on a fixed-point vocabulary; the firmware models run it
on numbers. Here ``fx`` and ``fw`` are symbolic (:class:`SymFx`, :class:`SymFw`): every word of
the vocabulary (``+``, ``-``, ``>>`` of a check word, ``*`` of check words, comparisons, ``|``,
``saturate``, ``select``, ``mul_const``, the exact products, ``atan2_angle``, ``cordic_rotate``,
``isqrt``, ``acos_of_complements``...) records a :class:`Node` instead of computing, so running
the body once yields its dataflow graph: the joint words and the status bits as functions of the
input words and the branch flags. :mod:`.seq_lower` turns the graph into blocks of the engine's
instructions and :mod:`.seq_schedule` places them on the units.

Nodes are hash-consed (the same operation on the same operands is one node) and carry an interval
bound of their value (``lo``, ``hi``): it sizes the multiplier's operands and drops clips that
cannot clip. A branch of the body on a symbolic value raises (the body selects instead).
"""

from __future__ import annotations

from math import isqrt

from ik5r.core import fixedpoint, ik
from ik5r.core.fxconfig import Constants
from ik5r.core.status import SATURATED

from ..sequenced.isa import C_BACK, C_DOWN, C_ROLL, INPUT_WORDS


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
        return self.g.node("neg", (self,), lo=-self.hi, hi=-self.lo)

    def __rshift__(self, n: int):
        if n != self.g.ki.check_shift:
            raise NotImplementedError(f"{self} >> {n}: only the check word shift is an engine word")
        return self.g.node("check", (self,), cls=Check)

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
        while isinstance(value, Node) and value.op in ("sat", "sqrt"):
            value = value.args[0]
        return Not(compare(value, ">", 0))


class Input(Node):
    """An input word (word format); ``<< guard`` is the internal word the engine reads in, and
    ``>> check_shift`` of the word format its check word."""

    def __lshift__(self, n: int):
        if n != self.g.guard:
            raise NotImplementedError("an input word is shifted by the internal guard bits only")
        return self.g.node("in", (), (self.params[0],))

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
    return g.node("add", (a, b), lo=a.lo + blo, hi=a.hi + bhi)


def sub(g, a, b):
    if isinstance(b, int) and b == 0:
        return a
    # c - (c - x) is x (1 - (1 - c3), the cosine an acos of complements gets back).
    if (isinstance(a, int) and getattr(b, "op", None) == "sub" and isinstance(b.args[0], int)
            and b.args[0] == a):
        return b.args[1]
    alo, ahi = (a, a) if isinstance(a, int) else (a.lo, a.hi)
    blo, bhi = (b, b) if isinstance(b, int) else (b.lo, b.hi)
    return g.node("sub", (a, b), lo=alo - bhi, hi=ahi - blo)


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
    """A branch flag of the flags word (``C_ROLL``, ``C_BACK``, ``C_DOWN``)."""

    def __init__(self, source: int):
        self.source = source


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
        return Status((ev, bit, gates + ((flag.source, 0),)) for ev, bit, gates in self.leaves)


# --- the vocabulary -----------------------------------------------------------------------------


class SymFx:
    """:mod:`ik5r.core.fixedpoint`'s words, recording nodes."""

    def __init__(self, g: Graph):
        self.g = g

    def saturate(self, value, k: Constants):
        bits = k.cfg.width
        if isinstance(value, Sop):
            raise NotImplementedError("saturate an exact sum (round it first)")
        lo, hi = self.g.word_range(bits)
        n = self.g.node("sat", (value,), (bits,), max(lo, min(hi, value.lo)), min(hi, max(lo, value.hi)))
        return n, Status(((n, SATURATED, ()),))

    def rshift_round(self, value, shift: int, nearest: bool):
        if shift <= 0:
            return value
        half = (1 << (shift - 1)) if nearest else 0
        lo, hi = (value.bounds() if isinstance(value, Sop) else (value.lo, value.hi))
        return self.g.node("rsr", (value,), (shift,), (lo + half) >> shift, (hi + half) >> shift)

    def mul_const(self, value, m, nearest: bool):
        ends = [fixedpoint.mul_const(v, m, nearest) for v in (value.lo, value.hi)]
        return self.g.node("mulc", (value,), (m,), min(ends), max(ends))

    def wrap_angle(self, value, k: Constants):
        pi = self.g.ki.pi_a
        if -pi <= value.lo and value.hi <= pi:
            return value          # provably within [-pi, pi]: nothing to wrap
        return self.g.node("wrap", (value,), lo=-pi, hi=pi)

    def opposite(self, value, k: Constants):
        return self.g.node("opp", (value,))

    def select(self, cond, if_true, if_false):
        if isinstance(if_true, Status):
            if not (isinstance(if_false, int) and if_false == 0 and isinstance(cond, Flag)):
                raise NotImplementedError("status selected against 0 by a branch flag only")
            return if_true.gated(cond)
        lo = min(v if isinstance(v, int) else v.lo for v in (if_true, if_false))
        hi = max(v if isinstance(v, int) else v.hi for v in (if_true, if_false))
        return self.g.node("sel", (if_true, if_false), (cond,), lo, hi)

    def flag(self, cond, bit: int):
        return Status(((cond, bit, ()),))

    def clip(self, value, low: int, high: int):
        if low <= value.lo and value.hi <= high:
            return value          # provably within: nothing to clip
        return self.g.node("clip", (value,), (low, high), max(low, value.lo), min(high, value.hi))

    def minimum(self, a, b):
        if isinstance(a, int):
            a, b = b, a
        if a.hi <= b:
            return a
        return self.g.node("clip", (a,), (None, b), min(a.lo, b), b)

    def any_of(self, cond) -> bool:
        return True               # one program for every pose: the roll path runs, gated by roll

    def exact_mul(self, a, b, k):
        return Sop(self.g, [(a, b, False, 0)], 0)

    def exact_const(self, value, k):
        return Sop(self.g, [], value)

    def exact_add(self, x, y):
        if isinstance(x, Node) or isinstance(y, Node):
            return add(self.g, *(v.const if isinstance(v, Sop) and not v.terms else v for v in (x, y)))
        return x + y

    def exact_sub(self, x, y):
        if isinstance(x, Node) or isinstance(y, Node):
            return sub(self.g, *(v.const if isinstance(v, Sop) and not v.terms else v for v in (x, y)))
        return x - y

    def exact_less(self, x, y):
        if not x.terms:
            return compare(y, ">", x.const)
        if not y.terms:
            return compare(x, "<", y.const)
        raise NotImplementedError("exact comparison of two sums")

    def exact_clip(self, value, bound):
        lo, hi = value.bounds()
        b = bound.const
        return self.g.node("clip", (value,), (-b, b), max(-b, lo), min(b, hi))

    def sum_of_squares(self, x, y, k):
        return Sop(self.g, [(x, x, False, 0), (y, y, False, 0)], 0)

    def mul_round(self, a, b, shift, nearest, k):
        return self.rshift_round(Sop(self.g, [(a, b, False, 0)], 0), shift, nearest)

    def dot_round(self, a1, b1, a2, b2, shift, nearest, k):
        terms = [(a.args[0], b, True, 0) if getattr(a, "op", None) == "neg" else (a, b, False, 0)
                 for a, b in ((a1, b1), (a2, b2))]
        return self.rshift_round(Sop(self.g, terms, 0), shift, nearest)


class SymFw:
    """The CORDIC and square-root kernels, recording nodes (the engine runs them as units)."""

    def __init__(self, g: Graph, fx: SymFx):
        self.g, self.fx = g, fx

    def atan2_angle(self, y, x, k):
        # The vectoring's z stays within the coarse quarter turn plus the sum of the step angles
        # (< 3.4 rad): two pi bounds it with room.
        pi = self.g.ki.pi_a
        n = self.g.node("atan2", (y, x), lo=-2 * pi, hi=2 * pi)
        return n, Zero(n)

    def cordic_rotate(self, x, y, angle, k):
        r = self.g.node("rot", (x, y, angle))
        return (self.g.node("rotx", (r,)), self.g.node("roty", (r,)), Status(((r, SATURATED, ()),)))

    def isqrt(self, radicand, bits: int, nearest: bool):
        lo, hi = radicand.bounds()
        if lo < 0:
            raise ValueError("negative radicand")
        return self.g.node("sqrt", (radicand,), (bits,), isqrt(lo), isqrt(hi) + 1)

    def acos_of_complements(self, one_minus, one_plus, k):
        """``model.acos_of_complements`` in the vocabulary: atan2(isqrt((1-x)(1+x)), 1 - (1-x))."""
        c = self.g.ki.cfg
        sine = self.isqrt(self.fx.exact_mul(one_minus, one_plus, k), 2 * c.frac_unit + 4, c.round_nearest)
        angle, _ = self.atan2_angle(sine, self.g.ki.one_u - one_minus, k)
        return angle, sine

    def cordic_acos(self, x, k):
        one = self.g.ki.one_u
        clipped = self.fx.clip(x, -one, one)
        if clipped is not x:
            raise NotImplementedError("cordic_acos of a value that may leave [-1, 1] (its flag)")
        angle, sine = self.acos_of_complements(one - x, one + x, k)
        return angle, sine, Status()


def trace(k: Constants):
    """``ik.solve`` on symbols: (the five joint nodes, the status leaves, the graph)."""
    g = Graph(k)
    fx = SymFx(g)
    words = {name: g.node("word", (), (name,), *g.word_range(k.cfg.width), cls=Input)
             for name in INPUT_WORDS}
    p, a, n, o = ([words[f"{v}{axis}"] for axis in "xyz"] for v in "pano")
    joints, status = ik.solve(fx, SymFw(g, fx), k, p, a, n, o, Flag(C_ROLL), Flag(C_BACK),
                              Flag(C_DOWN), words["q5d"])
    return joints, status, g
