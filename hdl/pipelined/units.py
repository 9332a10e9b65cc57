"""The units of the IK core generated from the traced IK (:mod:`.ik_graph`): one unit per value
of the graph of :func:`ik5r.hdl.graph.trace.trace`, a list of stages over named values.

A unit reads the values of its operands from the state in its first stage and leaves its results
in the state after its last one; its stages are flattened to one function per clock
(``latency`` steps; a unit of latency 0 is wiring in the stage of its start). The heavy operations run the blocks' public
chains (atan2 and the rotation of :mod:`.cordic`, the square root of :mod:`.sqrt`, the
multipliers of :mod:`.products`); the glue (:mod:`.ik_glue`) is one stage of logic per step,
widths from the node's interval bounds (:mod:`.seq_trace`: the sequenced core's memory words are sized by the same
bounds). The semantics of each op are those of :mod:`.seq_lower` (bit-exact on the compact core):
``fixedpoint``'s words on integers.
"""

from __future__ import annotations

from dataclasses import dataclass

from amaranth.hdl import Const, signed, unsigned

from ik5r.core import fixedpoint

from ..blocks.chains import compose, namespaced
from ..blocks.cordic import Rotate, add_atan2
from ..datapath.stages import Datapath, Stage, StageKind
from ..datapath.expr import drop, rshift_round
from .const_rotate import rotate_const_chain
from ..datapath.products import add_products
from ..graph.nodes import Check, Node, Sop, Zero, bits_of
from ..blocks.sqrt import add_isqrt, fit

__all__ = ["Unit", "Ctx", "Derived", "flatten", "shape_of", "sop_unit", "mulc_unit", "atan2_unit",
           "rotate_unit", "sqrt_unit"]


class Unit:
    """Steps computing ``writes`` from ``reads`` (value objects; ints are constants)."""

    def __init__(self, name, reads, writes, stages, *, wiring=False, shapes=None):
        reads = [r.args[0] if isinstance(r, Check) else r for r in reads if not isinstance(r, int)]
        self.name, self.reads, self.writes = name, reads, writes
        self.stages, self.wiring, self.shapes = list(stages), wiring, dict(shapes or {})
        self._steps = None

    @property
    def steps(self) -> list:
        """One function per clock (pipelined; a wiring unit's one function is wiring)."""
        if self._steps is None:
            self._steps = [self.stages[0].fn] if self.wiring else flatten(self.stages)
        return self._steps

    @property
    def latency(self) -> int:
        """Clocks from the operands to the results (a wiring unit's 0)."""
        return 0 if self.wiring else len(self.steps)


def flatten(stages) -> list:
    """Stages as one function per clock (iterated stages unrolled, as the pipelined
    build does); wiring stages composed into a neighbour."""
    steps, pending, carried = [], [], None
    for stage in map(Stage.of, stages):
        if stage.count == 0:
            pending.append(stage.fn)
            continue
        fns = [stage.fn] if not stage.iterated else [
            (lambda s, fn=stage.fn, i=i: fn(s, i)) for i in range(stage.count)]
        if stage.iterated:
            fns[-1], next_carried = _last_iteration(fns[-1])
        for fn in fns:
            if carried is not None:
                fn, carried = _reading_carried(fn, carried), None
            steps.append(compose(*pending, fn) if pending else fn)
            pending = []
        if stage.iterated:
            carried = next_carried
    if pending:
        steps[-1] = compose(steps[-1], *pending)
    return steps


def _last_iteration(fn):
    """The last step of an iterated stage, noting (when the construction check traces it) the
    values it reads and replaces: as in :meth:`Datapath.check`, they count as read by the
    stage's own (absent) next step, e.g. the y of a vectoring CORDIC, driven to 0."""
    carried = set()

    def run(s):
        before = set(getattr(s, "reads", ()))
        out = fn(s)
        if _tracing(s):
            carried.update(key for key in set(s.reads) - before if key in out
                           and dict.__contains__(s, key) and out[key] is not dict.__getitem__(s, key))
        return out
    return run, carried


def _tracing(s) -> bool:
    """``s`` is a state of the construction check (it records the keys read)."""
    return getattr(s, "reads", None) is not None


def _reading_carried(fn, carried):
    """``fn`` marking ``carried`` read (the construction check only)."""
    def run(s):
        if _tracing(s):
            for key in carried:
                if dict.__contains__(s, key):
                    s[key]
        return fn(s)
    return run


def _registered(name, *fns):
    return [Stage(f"{name}_{i}", StageKind.REGISTERED, fn) for i, fn in enumerate(fns)]


def _wiring(fn):
    return Stage("wiring", StageKind.WIRING, fn, 0)


def shape_of(v):
    """The register shape of a value from its interval bounds."""
    lo, hi = v.bounds() if isinstance(v, Sop) else (v.lo, v.hi)
    return unsigned(max(hi.bit_length(), 1)) if lo >= 0 else signed(bits_of(lo, hi))


class Ctx:
    """What a unit builder needs: the internal constants, the adders, the key of a value, the
    values the core needs (``needed``: a unit leaves only those)."""

    def __init__(self, ki, adders, key):
        self.ki, self.adders, self.key = ki, adders, key
        self.needed: set = set()
        self._derived: dict = {}

    def derived(self, kind: str, node) -> "Derived":
        """The one object naming the second result ``kind`` of ``node``'s unit."""
        # By the node's id: a tuple holding the node would compare nodes on a hash collision
        # (a node's == records a condition).
        if (kind, node.id) not in self._derived:
            self._derived[kind, node.id] = Derived(kind, node)
        return self._derived[kind, node.id]

    def canon(self, v):
        """The value object of ``v`` (an atan2's zero vector: its unit's second result)."""
        return self.derived("zero", v.atan2) if isinstance(v, Zero) else v

    def chain(self, name) -> Datapath:
        """A scratch chain with the core's multiplier schedule and adders."""
        return Datapath(name, adders=self.adders)

    def get(self, s, v):
        """The value of ``v`` in state ``s`` (a constant as itself)."""
        if isinstance(v, int):
            return Const(v, signed(bits_of(v, v)))
        if isinstance(v, Check):
            return self.get(s, v.args[0]).shift_right(self.ki.check_shift)
        return s[self.key(v)]

    def word_of(self, s, v):
        """``v`` as a signed word where its bounds fit one (a block's operand), else as it is
        (an angle whose loose bound passes a word: the blocks take it in their own widths)."""
        if not isinstance(v, int) and bits_of(v.lo, v.hi) > self.ki.cfg.width:
            return self.get(s, v)
        return fit(self.get(s, v), self.ki.cfg.width).as_signed()

    def glue(self, name, reads, writes, fn):
        """One stage: ``writes`` = ``fn(*values of reads)``."""
        def step(s):
            values = fn(*(self.get(s, r) for r in reads))
            return dict(s, **{self.key(w): v for w, v in zip(writes, values) if w in self.needed})
        return Unit(name, reads, writes, _registered(name, step),
                    shapes={self.key(w): _shape(w) for w in writes})

    def selecting(self, name, reads, write, compares, fn):
        """Two stages: the compares of the operands registered, then ``fn(flags, *operands)``
        (a compare and a select as wide as the word in one stage was the slow path, see
        :func:`~ik5r.hdl.blocks.chains.add_selecting`)."""
        inner = [f"{name}__a{i}" for i in range(len(reads))]
        flags = [f"{name}__f{i}" for i in range(len(compares))]

        def first(s):
            values = [self.get(s, r) for r in reads]
            out = dict(s, **dict(zip(inner, values)))
            out.update({f: c(*values) for f, c in zip(flags, compares)})
            return out

        def second(s):
            out = drop(s, *inner, *flags)
            out[self.key(write)] = fn([s[f] for f in flags], *(s[i] for i in inner))
            return out
        stages = _registered(name, first, second)
        return Unit(name, reads, [write], stages, shapes={self.key(write): _shape(write)})

    def chain_unit(self, name, chain, inputs: dict, outputs: dict):
        """A block's chain under the namespace ``name__``: ``inputs`` {chain key: fn(state)},
        ``outputs`` {chain key: value object}; outputs the core does not need are dropped."""
        prefix = f"{name}__"
        inner = namespaced(chain, prefix)

        def first(s):
            return dict(s, **{prefix + ck: fn(s) for ck, fn in inputs.items()})

        def last(s):
            # Decided when the stages run: the core's needed values are known by then.
            kept = {ck: v for ck, v in outputs.items() if v in self.needed}
            out = drop(s, *(prefix + ck for ck in outputs))
            out.update({self.key(v): s[prefix + ck] for ck, v in kept.items()})
            return out
        reads = [r for fn in inputs.values() for r in getattr(fn, "reads", ())]
        # ``last`` in the chain's last (registered) stage: an output not needed is not registered.
        *body, end = inner.stages
        return Unit(name, reads, list(outputs.values()),
                    [_wiring(first), *body, end.with_fn(compose(end.fn, last), shared=end.shared)],
                    shapes=inner.shapes)


def _shape(v):
    if isinstance(v, (Node, Sop)):
        return shape_of(v)
    return unsigned(1)


def _reading(fn, *reads):
    fn.reads = reads
    return fn


# --- the units of the graph's operations ----------------------------------------------------------

@dataclass(frozen=True, eq=False, slots=True)
class Derived:
    """A second result of a unit: ``"flag"`` (a saturation's or a rotation's status bit),
    ``"zero"`` (an atan2's zero vector); one object per result (:meth:`Ctx.derived`)."""
    kind: str
    node: Node


def _operand_shape(ctx, v):
    """A multiplier operand's shape (a check word: the top bits of its value)."""
    if isinstance(v, Check):
        inner, shift = v.args[0], ctx.ki.check_shift
        return signed(bits_of(inner.lo >> shift, inner.hi >> shift))
    return shape_of(v)


def sop_unit(ctx, name, s: Sop) -> Unit:
    """An exact sum of products: every product at once (:func:`add_products`), then the terms
    (and the constant) summed pairwise, one adder or subtractor level per stage; a check word
    shifted up (``b`` = 1) is a term without a product."""
    chain = ctx.chain(name)
    specs, terms, plain, reads = [], [], {}, []
    for i, (a, b, neg, shift) in enumerate(s.terms):
        reads += [a, b]
        key = f"{name}_t{i}"
        if isinstance(b, int) and b == 1:
            plain[key] = (lambda st, a=a: ctx.get(st, a))
        else:
            if isinstance(b, int):
                neg, b_spec = neg ^ (b < 0), abs(b)
            else:
                b_spec = ((lambda st, b=b: ctx.get(st, b)), _operand_shape(ctx, b))
            specs.append(((lambda st, a=a: ctx.get(st, a)), _operand_shape(ctx, a), b_spec, key))
        terms.append((key, neg, shift))
    if specs:
        add_products(chain, f"{name}_m", specs, parallel=lambda st: {k: f(st) for k, f in plain.items()})
    else:
        chain.add(f"{name}_op", lambda st: dict(st, **{k: f(st) for k, f in plain.items()}))
    items = [((lambda st, k=k, sh=sh: st[k].shift_left(sh)), neg) for k, neg, sh in terms]
    if s.const:
        items.append(((lambda st: Const(abs(s.const), signed(bits_of(s.const, s.const)))), s.const < 0))
    _add_sum(chain, name, items, [k for k, _, _ in terms], ctx.key(s))
    reads = [r.args[0] if isinstance(r, Check) else r for r in reads]
    return Unit(name, reads, [s], chain.stages, shapes=chain.shapes)


def _add_sum(chain, name, items, keys, out_key):
    """The sum of ``items`` ((fn(state), negative)) into ``out_key``: pairwise, one adder (or
    subtractor) level per stage; a lone positive term is wiring."""
    level = 0
    while len(items) > 1 or items[0][1]:
        pairs = [items[i:i + 2] for i in range(0, len(items), 2)]
        out_keys = [f"{name}_s{level}_{i}" for i in range(len(pairs))] if len(pairs) > 1 else [out_key]

        def step(st, pairs=pairs, out_keys=out_keys, keys=keys):
            out = drop(st, *keys)
            for key, pair in zip(out_keys, pairs):
                out[key] = _signed_sum(st, pair)
            if len(pairs) == 1 and _both_negative(pairs[0]):
                out[out_key] = -out[out_key]      # the last level: no level left to negate it
            return out
        chain.add(f"{name}_sum{level}", step)
        if len(pairs) == 1:
            return
        items = [((lambda st, k=k: st[k]), _both_negative(pair)) for k, pair in zip(out_keys, pairs)]
        keys, level = out_keys, level + 1
    fn = items[0][0]
    chain.add_wiring(lambda st: dict(drop(st, *keys), **{out_key: fn(st)}))


def _both_negative(pair) -> bool:
    return len(pair) == 2 and pair[0][1] and pair[1][1]


def _signed_sum(st, pair):
    """One adder: a + b, a - b or b - a (both negative: the sum, whose negation is the next
    level's); a lone negative item negated."""
    (fa, na), *rest = pair
    if not rest:
        return -fa(st) if na else fa(st)
    fb, nb = rest[0]
    if na == nb:
        return fa(st) + fb(st)
    return fa(st) - fb(st) if nb else fb(st) - fa(st)


def mulc_unit(ctx, name, n) -> Unit:
    """``fixedpoint.mul_const``: the pre-shift's rounding into the operand register, the
    mantissa's product, the post-shift's rounding."""
    x, m = n.args[0], n.params[0]
    nearest = ctx.ki.cfg.round_nearest
    ends = [fixedpoint.rshift_round(v, m.pre, nearest) for v in (x.lo, x.hi)]
    chain = ctx.chain(name)
    add_products(chain, f"{name}_m", [(lambda s: rshift_round(ctx.get(s, x), m.pre, nearest),
                                       signed(bits_of(min(ends), max(ends))), abs(m.mant), f"{name}_p")])

    def post(s):
        p = -s[f"{name}_p"] if m.mant < 0 else s[f"{name}_p"]
        return dict(drop(s, f"{name}_p"), **{ctx.key(n): rshift_round(p, m.post, nearest)})
    chain.add(f"{name}_post", post)
    return Unit(name, [x], [n], chain.stages, shapes={**chain.shapes, ctx.key(n): shape_of(n)})


def atan2_unit(ctx, name, n) -> Unit:
    """``model.cordic_atan2``: the atan2 block's chain; the angle and the zero vector."""
    y, x = n.args
    chain = Datapath(name, adders=ctx.adders)
    add_atan2(chain, ctx.ki, y="y", x="x", magnitude=False, zero=True)
    return ctx.chain_unit(name, chain, {"y": _reading(lambda s: ctx.word_of(s, y), y),
                                        "x": _reading(lambda s: ctx.word_of(s, x), x)},
                          {"angle": n, "zero": ctx.derived("zero", n)})


def rotate_unit(ctx, name, r) -> Unit:
    """``model.cordic_rotate``: of a constant vector the rotation's constant quadrant step
    (:func:`rotate_const_chain`), else the rotation block's chain; x, y and the saturation."""
    x, y, angle = r.args
    outputs = {"saturated": ctx.derived("flag", r), **r.g.outputs_of(r)}
    angle_of = _reading(lambda s: ctx.word_of(s, angle), angle)
    if isinstance(x, int) and isinstance(y, int):
        chain = rotate_const_chain(ctx.ki, (x, y), skewed=True, adders=ctx.adders)
        return ctx.chain_unit(name, chain, {"angle": angle_of}, outputs)
    chain = Rotate.chain(ctx.ki, skewed=True, adders=ctx.adders)
    return ctx.chain_unit(name, chain, {"x": _reading(lambda s: ctx.word_of(s, x), x),
                                        "y": _reading(lambda s: ctx.word_of(s, y), y),
                                        "angle": angle_of}, outputs)


def sqrt_unit(ctx, name, n) -> Unit:
    """``model.isqrt(radicand, bits)``: the square root's digit stages on the radicand's low
    ``bits`` bits (all the model reads)."""
    rad, bits = n.args[0], n.params[0]
    chain = Datapath(name, adders=ctx.adders)
    add_isqrt(chain, bits=bits, nearest=ctx.ki.cfg.round_nearest, root="root")
    unit = ctx.chain_unit(name, chain, {"sq_rad": _reading(lambda s: fit(ctx.get(s, rad), bits), rad)},
                          {"root": n})
    unit.shapes[ctx.key(n)] = shape_of(n)
    return unit
