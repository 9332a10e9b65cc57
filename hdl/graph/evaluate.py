"""The traced graph run on numbers: each node by its operation's meaning
(:data:`~.registry.SPECS`), on the vocabulary and kernels :func:`ik5r.core.ik.solve` runs on.

With ``ik5r.core.fixedpoint`` and the model's kernels it evaluates one pose on Python integers;
with ``ik5r.core.fixedpoint_np`` and the vectorised model's kernels a batch on numpy arrays. Run
beside ``ik.solve`` on the same words it checks the tracer: the graph the cores are built from
computes what the body computes, bit for bit (``tests/test_ir.py``). The kernels are passed in:
the graph sits beside the firmware model and imports none of it.
"""

from __future__ import annotations

from ik5r.core.fxconfig import Constants

from .inputs import BranchFlag
from .nodes import AnyOf, Flag, Node, Not, Sop, Zero
from .registry import SPECS

__all__ = ["Evaluation", "evaluate"]


class Evaluation:
    """The values of one graph's nodes for one set of input words and branch flags."""

    def __init__(self, fx, fw, k: Constants, words: dict, flags: dict):
        self.fx, self.fw, self.k, self.ki = fx, fw, k, k.internal
        self.guard, self.nearest = k.cfg.internal_guard_bits, k.internal.cfg.round_nearest
        self.words, self.flags = words, flags
        self.results: dict = {}

    def of_width(self, bits: int) -> Constants:
        """The format (word or internal) whose words are ``bits`` wide."""
        return self.k if bits == self.k.cfg.width else self.ki

    def run(self, nodes):
        """Every node in trace order (a node's arguments come before it)."""
        for n in nodes:
            if isinstance(n, Sop):
                self.results[n] = self._sum(n)
            else:
                spec = SPECS[n.op]
                self.results[n] = spec.meaning(self, n, *(self.value(a) for a in n.args))

    def value(self, v):
        """The value of an argument: an integer, or a node's (first) result."""
        if isinstance(v, int):
            return v
        result = self.results[v]
        return result[0] if isinstance(v, Node) and SPECS[v.op].results > 1 else result

    def exact(self, n: Node, *values) -> list:
        """The values of ``n``'s arguments as exact products (a constant or a word lifted)."""
        fx, ki = self.fx, self.ki
        return [fx.exact_const(v, ki) if isinstance(arg, int) else v if arg.exact else fx.exact_mul(v, 1, ki)
                for arg, v in zip(n.args, values)]

    def second(self, n: Node):
        """A saturation's or a rotation's flag, an atan2's zero vector."""
        return self.results[n][-1]

    def cond(self, c):
        fx = self.fx
        if isinstance(c, Flag):
            return self.flags[c.flag]
        if isinstance(c, Zero):
            return self.second(c.atan2)
        if isinstance(c, Not):
            return fx.select(self.cond(c.cond), False, True)
        if isinstance(c, AnyOf):
            out = self.cond(c.conds[0])
            for other in c.conds[1:]:
                out = out | self.cond(other)
            return out
        v = self.value(c.value)
        if isinstance(c.value, Sop) and not c.value.of_check_words:
            const = fx.exact_const(c.const, self.ki)
            return fx.exact_less(const, v) if c.op == ">" else fx.exact_less(v, const)
        return v > c.const if c.op == ">" else v < c.const

    def _sum(self, s: Sop):
        """An exact sum of products with the vocabulary's exact words (a sum of two squares as
        ``sum_of_squares``, the body's radicand); of check words, plain integers."""
        fx, terms = self.fx, s.terms
        if s.of_check_words:
            out = s.const
            for a, b, neg, shift in terms:
                p = (self.value(a) * self.value(b)) << shift
                out = out - p if neg else out + p
            return out
        if any(shift for *_, shift in terms):
            raise NotImplementedError(f"{s}: a shifted product of words")
        if not s.const and len(terms) == 2 and all(a is b and not neg for a, b, neg, _ in terms):
            return fx.sum_of_squares(self.value(terms[0][0]), self.value(terms[1][0]), self.ki)
        out = fx.exact_const(s.const, self.ki)
        for a, b, neg, _ in terms:
            p = fx.exact_mul(self.value(a), self.value(b), self.ki)
            out = fx.exact_sub(out, p) if neg else fx.exact_add(out, p)
        return out

    def status(self, events):
        """The status word: every leaf's bit where its event holds and its flags are set."""
        out = 0
        for leaf in events:
            event = leaf.event
            cond = self.second(event) != 0 if isinstance(event, Node) else self.cond(event)
            for flag, level in leaf.gates:
                cond = cond & (self.flags[flag] if level == 0 else ~self.flags[flag])
            out = out | self.fx.flag(cond, leaf.bit)
        return out


def evaluate(traced, fx, fw, k: Constants, p, a, n, o, roll, back, down, q5_default):
    """(the five joints, the status) of the traced graph for the words ``p``, ``a``, ``n``, ``o``
    (three each), the branch flags and the default q5: the arguments of ``ik.solve``."""
    words = dict(zip(("px", "py", "pz", "ax", "ay", "az", "nx", "ny", "nz", "ox", "oy", "oz"),
                     (*p, *a, *n, *o)), q5d=q5_default)
    ev = Evaluation(fx, fw, k, words, {BranchFlag.ROLL: roll, BranchFlag.BACK: back, BranchFlag.DOWN: down})
    joints, events, graph = traced
    ev.run(graph.nodes)
    return tuple(ev.value(j) for j in joints), ev.status(events)
