"""One entry per operation of the IR (:class:`~.ops.Op`): what a node of it takes, the interval
bound of its value, and what it computes.

:data:`SPECS` holds an :class:`OpSpec` for every member of ``Op``; :meth:`Graph.node
<.nodes.Graph.node>` checks a node's arity and sets its bound from it, and :mod:`.evaluate` runs
a graph with it on integers or on numpy arrays (the vocabulary ``fx`` and kernels ``fw`` that
:func:`ik5r.core.ik.solve` runs on). How each core builds an operation is a table of its own, keyed
by ``Op`` (``ik5r.hdl.sequenced.lower.LOWERING``, ``ik5r.hdl.pipelined.glue.UNITS``): the graph
sits below both cores and imports neither, so a core's table cannot live here; each table is
checked against ``Op`` with :func:`require_every_op` when its module is imported, so an operation
added here without a lowering fails at import, not when a core is generated.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import isqrt
from typing import Callable

from ik5r.core import fixedpoint

from .ops import Op

__all__ = ["OpSpec", "SPECS", "span", "require_every_op"]


def span(v) -> tuple[int, int]:
    """The interval of a value: an integer's own, a node's or an exact sum's bound."""
    return (v, v) if isinstance(v, int) else v.bounds()


@dataclass(frozen=True, slots=True)
class OpSpec:
    """What a node of ``op`` is.

    ``arity``: its arguments (nodes or integers); ``params``: the names of its parameters.
    ``bound(g, args, params)``: (lo, hi) of its value, ``None`` for the internal word's range.
    ``meaning(ev, node, *values)``: its value from its arguments' values (``ev``: an
    :class:`~.evaluate.Evaluation`, holding ``fx``, ``fw`` and the formats); an operation with a
    second result (a saturation's flag, an atan2's zero vector, a rotation's x, y and flag)
    returns a tuple, ``results`` items long, whose first item is the node's value (a rotation's
    value is its tuple: ``ROTX`` and ``ROTY`` take its items)."""
    op: Op
    arity: int
    params: tuple[str, ...]
    bound: Callable | None
    meaning: Callable
    results: int = 1


def _word(g, args, params):
    return g.word_range(g.k.cfg.width)


def _sat(g, args, params):
    lo, hi = g.word_range(params[0])
    vlo, vhi = span(args[0])
    return max(lo, min(hi, vlo)), min(hi, max(lo, vhi))


def _rsr(g, args, params):
    half = (1 << (params[0] - 1)) if g.ki.cfg.round_nearest else 0
    lo, hi = span(args[0])
    return (lo + half) >> params[0], (hi + half) >> params[0]


def _mulc(g, args, params):
    ends = [fixedpoint.mul_const(v, params[0], g.ki.cfg.round_nearest) for v in span(args[0])]
    return min(ends), max(ends)


def _clip(g, args, params):
    # ``minimum`` (no low end) keeps its low bound below the high end: the value may pass it.
    (low, high), (vlo, vhi) = params, span(args[0])
    return (min(vlo, high) if low is None else max(low, vlo)), min(high, vhi)


def _sel(g, args, params):
    return min(span(v)[0] for v in args), max(span(v)[1] for v in args)


def _saturate(ev, n, a):
    return ev.fx.saturate(a, ev.of_width(n.params[0]))


def _clip_value(ev, n, a):
    low, high = n.params
    if n.args[0].exact:
        return ev.fx.exact_clip(a, ev.fx.exact_const(high, ev.ki))
    return ev.fx.minimum(a, high) if low is None else ev.fx.clip(a, low, high)


def _spec(op, arity, params, bound, meaning, results=1) -> OpSpec:
    return OpSpec(op, arity, params, bound, meaning, results)


#: An atan2's vectoring z stays within the coarse quarter turn plus the sum of the step angles
#: (< 3.4 rad): two pi bounds it with room.
_ATAN2_TURNS = 2
SPECS: dict[Op, OpSpec] = {s.op: s for s in (
    _spec(Op.WORD, 0, ("name",), _word, lambda ev, n: ev.words[n.params[0]]),
    _spec(Op.INPUT, 0, ("name",), None, lambda ev, n: ev.words[n.params[0]] << ev.guard),
    _spec(Op.NEG, 1, (), lambda g, a, p: (-span(a[0])[1], -span(a[0])[0]), lambda ev, n, a: -a),
    _spec(Op.CHECK, 1, (), None, lambda ev, n, a: a >> ev.ki.check_shift),
    _spec(Op.ADD, 2, (), lambda g, a, p: (span(a[0])[0] + span(a[1])[0], span(a[0])[1] + span(a[1])[1]),
          lambda ev, n, a, b: ev.fx.exact_add(*ev.exact(n, a, b)) if n.exact else a + b),
    _spec(Op.SUB, 2, (), lambda g, a, p: (span(a[0])[0] - span(a[1])[1], span(a[0])[1] - span(a[1])[0]),
          lambda ev, n, a, b: ev.fx.exact_sub(*ev.exact(n, a, b)) if n.exact else a - b),
    _spec(Op.SAT, 1, ("bits",), _sat, _saturate, results=2),
    _spec(Op.RSR, 1, ("shift",), _rsr,
          lambda ev, n, a: ev.fx.rshift_round(a, n.params[0], ev.nearest)),
    _spec(Op.MULC, 1, ("constant",), _mulc, lambda ev, n, a: ev.fx.mul_const(a, n.params[0], ev.nearest)),
    _spec(Op.WRAP, 1, (), lambda g, a, p: (-g.ki.pi_a, g.ki.pi_a), lambda ev, n, a: ev.fx.wrap_angle(a, ev.ki)),
    _spec(Op.OPP, 1, (), None, lambda ev, n, a: ev.fx.opposite(a, ev.ki)),
    _spec(Op.SEL, 2, ("cond",), _sel, lambda ev, n, a, b: ev.fx.select(ev.cond(n.params[0]), a, b)),
    _spec(Op.CLIP, 1, ("low", "high"), _clip, _clip_value),
    _spec(Op.ATAN2, 2, (), lambda g, a, p: (-_ATAN2_TURNS * g.ki.pi_a, _ATAN2_TURNS * g.ki.pi_a),
          lambda ev, n, y, x: ev.fw.atan2_angle(y, x, ev.ki), results=2),
    _spec(Op.ROT, 3, (), None, lambda ev, n, x, y, angle: ev.fw.cordic_rotate(x, y, angle, ev.ki)),
    _spec(Op.ROTX, 1, (), None, lambda ev, n, r: r[0]),
    _spec(Op.ROTY, 1, (), None, lambda ev, n, r: r[1]),
    _spec(Op.SQRT, 1, ("bits",), lambda g, a, p: (isqrt(span(a[0])[0]), isqrt(span(a[0])[1]) + 1),
          lambda ev, n, a: ev.fw.isqrt(a, n.params[0], ev.nearest)),
)}


def require_every_op(table: dict, what: str, *, spare: tuple = ()) -> dict:
    """``table`` (keyed by :class:`~.ops.Op`) with an entry for every operation but ``spare``
    (the ones that never reach it, said where the table is made); raises naming the missing
    ones (a core's table is checked when its module is imported)."""
    missing = [op.name for op in Op if op not in table and op not in spare]
    extra = [op.name for op in spare if op in table]
    if missing or extra:
        raise NotImplementedError(f"{what}: no entry for {', '.join(missing) or '-'}"
                                  f"; spare but present: {', '.join(extra) or '-'}")
    return table


if set(SPECS) != set(Op):
    raise NotImplementedError(f"no OpSpec for {sorted(set(Op) - set(SPECS))}")
