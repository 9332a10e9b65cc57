"""The glue units of the pipelined IK core generated from the traced IK (:mod:`.graph`): adds,
selects, saturations, clips, wraps, the conditions as bits; :data:`UNITS`, the unit builder of
each operation of the IR (the heavy ones in :mod:`.units`), checked against the IR's registry
when this module is imported; and :func:`unit_of`, the unit of any value of the graph. The
meaning of each operation: :data:`ik5r.hdl.graph.registry.SPECS`. One adder level or one select
per stage; a compare that selects a value is registered a stage ahead of its select."""

from __future__ import annotations

from amaranth.hdl import Cat, Const, Mux

from ..graph.ops import Op
from ..datapath.expr import rshift_round, saturate
from .units import Unit, atan2_unit, mulc_unit, rotate_unit, sop_unit, sqrt_unit
from ..graph.nodes import AnyOf, Compare, Not, Sop
from ..graph.registry import require_every_op
from ..blocks.sqrt import fit

__all__ = ["unit_of", "UNITS"]


def _in_range(v, lo, hi) -> bool:
    vlo, vhi = v.bounds() if isinstance(v, Sop) else (v.lo, v.hi)
    return (lo is None or lo <= vlo) and (hi is None or vhi <= hi)


def _add(ctx, name, n) -> Unit:
    return ctx.glue(name, n.args, [n], lambda a, b: (a + b,))


def _sub(ctx, name, n) -> Unit:
    return ctx.glue(name, n.args, [n], lambda a, b: (a - b,))


def _neg(ctx, name, n) -> Unit:
    return ctx.glue(name, n.args, [n], lambda a: (-a,))


def _rsr(ctx, name, n) -> Unit:
    nearest = ctx.ki.cfg.round_nearest
    return ctx.glue(name, n.args, [n], lambda a: (rshift_round(a, n.params[0], nearest),))


def _sel(ctx, name, n) -> Unit:
    cond = ctx.canon(n.params[0])
    return ctx.glue(name, [cond, *n.args], [n], lambda c, a, b: (Mux(c, a, b),))


def _wrap(ctx, name, n) -> Unit:
    # One adder whose constant operand the registered flags pick (in the carry cells' LUTs),
    # not a select after two adders: the select's ripple after the carry chains was the
    # placed core's critical path.
    pi = ctx.ki.pi_a
    return ctx.selecting(name, n.args, n, [lambda a: a > pi, lambda a: a < -pi],
                         lambda f, a: a + Mux(f[0], -2 * pi, Mux(f[1], 2 * pi, 0)))


def _opp(ctx, name, n) -> Unit:
    pi = ctx.ki.pi_a
    return ctx.selecting(name, n.args, n, [lambda a: a > 0], lambda f, a: a + Mux(f[0], -pi, pi))


def _no_unit(ctx, name, n) -> Unit:
    raise NotImplementedError(f"{n} has no unit of its own (an input, a product's check word "
                              "or a rotation's output)")


def sat_unit(ctx, name, n) -> Unit:
    """``fixedpoint.saturate`` to ``bits``; wiring where the bounds show it never clips."""
    x, bits = n.args[0], n.params[0]
    flag = ctx.derived("flag", n)
    if _in_range(x, -(1 << (bits - 1)), (1 << (bits - 1)) - 1):
        unit = ctx.glue(name, [x], [n, flag], lambda a: (fit(a, bits).as_signed(), Const(0, 1)))
        unit.wiring = True
        return unit
    # expr.saturate reads a value as wide as the word as a word: an unsigned one gets its sign bit.
    return ctx.glue(name, [x], [n, flag], lambda a: saturate(
        a if a.shape().signed else Cat(a, Const(0, 1)).as_signed(), bits))


def clip_unit(ctx, name, n) -> Unit:
    """A clip to [lo, hi] (either end None: unbounded), only at the ends the value may pass."""
    x, (lo, hi) = n.args[0], n.params
    ends = [(c, end) for c, end in ((lambda a: a > hi, hi), (lambda a: a < lo, lo))
            if end is not None and not _in_range(x, *((None, end) if end is hi else (end, None)))]

    def select(f, a):
        for flag, (_, end) in reversed(list(zip(f, ends))):
            a = Mux(flag, end, a)
        return a
    return ctx.selecting(name, [x], n, [c for c, _ in ends], select)


def cond_unit(ctx, name, c) -> Unit:
    """A condition as a bit: a compare against a constant (one stage), Not and AnyOf (wiring).
    A sum of squares compared with 0 is the OR of its operands being non-zero."""
    if isinstance(c, Compare):
        v = c.value
        if (isinstance(v, Sop) and c.op == ">" and c.const == 0 and not v.const
                and all(a is b and not neg for a, b, neg, _ in v.terms)):
            operands = [a for a, _, _, _ in v.terms]
            return ctx.glue(name, operands, [c], lambda *xs: ((Const(0, 1) if not xs else
                                                              _any_nonzero(xs)),))
        if c.op == ">":
            return ctx.glue(name, [v], [c], lambda a: (a > c.const,))
        return ctx.glue(name, [v], [c], lambda a: (a < c.const,))
    if isinstance(c, Not):
        unit = ctx.glue(name, [ctx.canon(c.cond)], [c], lambda a: (~a,))
    elif isinstance(c, AnyOf):
        conds = [ctx.canon(x) for x in c.conds]
        unit = ctx.glue(name, conds, [c], lambda *xs: (_any(xs),))
    else:
        raise NotImplementedError(f"no pipelined unit for {c!r}")
    unit.wiring = True
    return unit


def _any(xs):
    out = xs[0]
    for x in xs[1:]:
        out = out | x
    return out


def _any_nonzero(xs):
    return _any([x != 0 for x in xs])


def unit_of(ctx, name, v) -> Unit:
    """The unit computing value ``v``."""
    if isinstance(v, Sop):
        return sop_unit(ctx, name, v)
    if isinstance(v, (Compare, Not, AnyOf)):
        return cond_unit(ctx, name, v)
    return UNITS[v.op](ctx, name, v)


#: The unit builder of each operation: ``builder(ctx, name, node) -> Unit``. The inputs
#: (``WORD``, ``INPUT``) are the core's payload, a ``CHECK`` is read by the products of its sum,
#: ``ROTX`` and ``ROTY`` are results of their ``ROT``'s unit (the schedule asks for the producer).
UNITS = require_every_op({
    Op.WORD: _no_unit, Op.INPUT: _no_unit, Op.CHECK: _no_unit, Op.ROTX: _no_unit, Op.ROTY: _no_unit,
    Op.ADD: _add, Op.SUB: _sub, Op.NEG: _neg, Op.RSR: _rsr, Op.SEL: _sel, Op.SAT: sat_unit,
    Op.WRAP: _wrap, Op.OPP: _opp, Op.CLIP: clip_unit, Op.MULC: mulc_unit, Op.ATAN2: atan2_unit,
    Op.ROT: rotate_unit, Op.SQRT: sqrt_unit,
}, "the pipelined core's units")
