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

from typing import NamedTuple

from ik5r.core import ik
from ik5r.core.fxconfig import Constants
from ik5r.core.status import SATURATED

from .inputs import INPUT_WORDS, BranchFlag
from .nodes import Flag, Graph, Input, Node, Sop, Zero, add, compare, sub
from .ops import Op
from .status import Status, StatusEvents


class SymFx:
    """:mod:`ik5r.core.fixedpoint`'s words, recording nodes."""

    def __init__(self, g: Graph):
        self.g = g

    def saturate(self, value, k: Constants):
        bits = k.cfg.width
        if isinstance(value, Sop):
            raise NotImplementedError("saturate an exact sum (round it first)")
        n = self.g.node(Op.SAT, (value,), (bits,))
        return n, Status(((n, SATURATED, ()),))

    def rshift_round(self, value, shift: int, nearest: bool):
        if shift <= 0:
            return value
        _rounding(self.g, nearest)
        return self.g.node(Op.RSR, (value,), (shift,))

    def mul_const(self, value, m, nearest: bool):
        _rounding(self.g, nearest)
        return self.g.node(Op.MULC, (value,), (m,))

    def wrap_angle(self, value, k: Constants):
        pi = self.g.ki.pi_a
        if -pi <= value.lo and value.hi <= pi:
            return value          # provably within [-pi, pi]: nothing to wrap
        return self.g.node(Op.WRAP, (value,))

    def opposite(self, value, k: Constants):
        return self.g.node(Op.OPP, (value,))

    def select(self, cond, if_true, if_false):
        if isinstance(if_true, Status):
            if not (isinstance(if_false, int) and if_false == 0 and isinstance(cond, Flag)):
                raise NotImplementedError("status selected against 0 by a branch flag only")
            return if_true.gated(cond)
        return self.g.node(Op.SEL, (if_true, if_false), (cond,))

    def flag(self, cond, bit: int):
        return Status(((cond, bit, ()),))

    def clip(self, value, low: int, high: int):
        if low <= value.lo and value.hi <= high:
            return value          # provably within: nothing to clip
        return self.g.node(Op.CLIP, (value,), (low, high))

    def minimum(self, a, b):
        if isinstance(a, int):
            a, b = b, a
        if a.hi <= b:
            return a
        return self.g.node(Op.CLIP, (a,), (None, b))

    def any_of(self, cond) -> bool:
        return True               # one program for every pose: the roll path runs, gated by roll

    def exact_mul(self, a, b, k):
        return self.g.sop([(a, b, False, 0)], 0)

    def exact_const(self, value, k):
        return self.g.sop([], value)

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
        b = bound.const
        return self.g.node(Op.CLIP, (value,), (-b, b))

    def sum_of_squares(self, x, y, k):
        return self.g.sop([(x, x, False, 0), (y, y, False, 0)], 0)

    def mul_round(self, a, b, shift, nearest, k):
        return self.rshift_round(self.g.sop([(a, b, False, 0)], 0), shift, nearest)

    def dot_round(self, a1, b1, a2, b2, shift, nearest, k):
        terms = [(a.args[0], b, True, 0) if getattr(a, "op", None) == Op.NEG else (a, b, False, 0)
                 for a, b in ((a1, b1), (a2, b2))]
        return self.rshift_round(self.g.sop(terms, 0), shift, nearest)


class SymFw:
    """The CORDIC and square-root kernels, recording nodes (the engine runs them as units)."""

    def __init__(self, g: Graph, fx: SymFx):
        self.g, self.fx = g, fx

    def atan2_angle(self, y, x, k):
        n = self.g.node(Op.ATAN2, (y, x))
        return n, Zero(n)

    def cordic_rotate(self, x, y, angle, k):
        r = self.g.node(Op.ROT, (x, y, angle))
        return (self.g.node(Op.ROTX, (r,)), self.g.node(Op.ROTY, (r,)), Status(((r, SATURATED, ()),)))

    def isqrt(self, radicand, bits: int, nearest: bool):
        if radicand.bounds()[0] < 0:
            raise ValueError("negative radicand")
        _rounding(self.g, nearest)
        return self.g.node(Op.SQRT, (radicand,), (bits,))

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


def _rounding(g: Graph, nearest: bool):
    """Both cores round as the config says (an operation's parameters do not carry it)."""
    if nearest != g.ki.cfg.round_nearest:
        raise NotImplementedError("a rounding other than the config's")


class Traced(NamedTuple):
    """The traced IK: the five joint nodes, the status leaves beside the graph, the graph."""
    joints: tuple
    events: StatusEvents
    graph: Graph


def trace(k: Constants) -> Traced:
    """``ik.solve`` on symbols."""
    g = Graph(k)
    fx = SymFx(g)
    words = {name: g.node(Op.WORD, (), (name,), cls=Input)
             for name in INPUT_WORDS}
    p, a, n, o = ([words[f"{v}{axis}"] for axis in "xyz"] for v in "pano")
    joints, status = ik.solve(fx, SymFw(g, fx), k, p, a, n, o, Flag(BranchFlag.ROLL),
                              Flag(BranchFlag.BACK), Flag(BranchFlag.DOWN), words["q5d"])
    return Traced(tuple(joints), StatusEvents(status), g)
