"""The traced IK graph (:mod:`.seq_trace`) lowered to blocks of the sequenced engine's instructions.

A block is a straight run of instructions that starts from memory words and constants and ends by
storing its value (or, for a status-only check, by its compare events): the accumulator, the F
flag and the units hold nothing from one block to the next, so :mod:`.seq_schedule` may place
blocks anywhere their memory words are ready. A value used once is computed inside its consumer's
block (in the accumulator), unless it is long (a CORDIC, a square root, products) and the consumer
also waits for another block's word; a value used more than once, or read as a B-bus operand,
gets its own block and a memory word. An exact sum of products (wider than a memory word) is
never stored: each consumer forms it again (the radicand of joint 1's root and the on-axis test).
Status bits are events on the instruction that decides them (the trace's
:class:`~ik5r.hdl.graph.status.StatusEvents`): the saturation's ``SATI`` / ``SATW``, a compare
against a constant, the CORDIC's zero-vector latch; ``select(flag, status, 0)`` adds the flag to
their conditions.

How each operation is lowered is :data:`LOWERING`, one entry per :class:`~ik5r.hdl.graph.ops.Op`,
checked against the IR's registry when this module is imported.
"""

from __future__ import annotations

from collections import Counter

from ..graph.ops import Op
from .isa import (A_ADD, A_CMPGT, A_CMPLT, A_LD, A_NEG, A_NOP, A_SATI, A_SATW, A_SUB, C_F, C_ZERO,
                      FLAG_SOURCE, IO_FLAGS, IO_IN, IO_OUT, IO_STATUS, B_IN, K_LDXG, K_LDYG, Q_LOAD,
                      Q_STEP, Q_STEP2)
from ..graph.inputs import INPUT_WORDS
from .asm import Asm, Check as CheckOperand, Const, I, alu, operand as _op, sqrt_round, st
from ..graph.nodes import Check, Flag, Node, Not, Sop
from ..graph.registry import require_every_op
from ..graph.status import StatusEvents


#: Operations that occupy a unit for many clocks.
HEAVY = (Op.ATAN2, Op.SQRT, Op.MULC, Op.ROT, Op.ROTX, Op.ROTY)


def _carriers(events: StatusEvents) -> list:
    """The values that carry status events (their blocks must run even where no joint needs
    their value), one per leaf; the engine raises each leaf on an instruction of its carrier."""
    carriers = [leaf.carrier for leaf in events]
    if any(c is None for c in carriers):
        raise NotImplementedError("a status bit of a negated compare")
    return carriers


def _gates(gates) -> tuple:
    """A leaf's branch flags as the engine's condition sources."""
    return tuple((FLAG_SOURCE[flag], level) for flag, level in gates)


def _cond_sel(v) -> bool:
    """A selection by a comparison (not a branch flag): only the CORDIC's operand loads take it."""
    return isinstance(v, Node) and v.op == Op.SEL and not isinstance(v.params[0], Flag)


def _compare_of(cond):
    """(the compared value, op, constant, F means cond)."""
    if isinstance(cond, Not):
        value, op, const, truth = _compare_of(cond.cond)
        return value, op, const, not truth
    return cond.value, cond.op, cond.const, True


def deps(n) -> list:
    """The values ``n``'s code reads (as the lowering emits it)."""
    if isinstance(n, Sop):
        return [v for a, b, _, _ in n.terms for v in (a, b) if not isinstance(v, int)]
    if n.op in (Op.WORD, Op.INPUT):
        return []
    if n.op == Op.SEL and isinstance(n.params[0], Flag):
        a, b = n.args
        if isinstance(a, Node) and a.op in (Op.NEG, Op.OPP) and a.args[0] is b:
            return [b]
        if isinstance(b, Node) and b.op in (Op.NEG, Op.OPP) and b.args[0] is a:
            return [a]
        if _add_sub(a, b):
            return list(a.args)
    if n.op == Op.SUB and _magnitude_of(n) is not None:
        return [_magnitude_of(n)]
    if n.op == Op.ATAN2:
        out = []
        for v in n.args:
            out += list(v.args) + [_compare_of(v.params[0])[0]] if _cond_sel(v) else [v]
        return list(dict.fromkeys(out))
    return [v for v in n.args if not isinstance(v, int)]


def _add_sub(a, b) -> bool:
    return (isinstance(a, Node) and isinstance(b, Node) and a.op == Op.ADD and b.op == Op.SUB
            and all(x is y for x, y in zip(a.args, b.args)))


class Lower:
    """Emits the blocks of a traced graph (``blocks[0]`` the inputs, ``blocks[-1]`` the outputs)."""

    def __init__(self, asm: Asm, joints: list, events: StatusEvents):
        self.a, self.ki, self.events = asm, asm.ki, events
        carriers = _carriers(events)
        self.uses: Counter = Counter()
        seen: set = set()

        def visit(n):
            for d in deps(n):
                self.uses[d] += 1
                if d not in seen:
                    seen.add(d)
                    visit(d)

        roots = list(joints) + [c for c in carriers if all(c is not j for j in joints)]
        for r in roots:
            if r not in seen:
                seen.add(r)
                visit(r)
        self.mem: dict = {}
        self.emitted: set = set()
        code = []
        for index, name in enumerate(INPUT_WORDS):
            code += [I(io=IO_IN, iw=index, bsel=B_IN, alu=A_LD), st(name)]
        self.blocks = [code + [I(io=IO_FLAGS, iw=len(INPUT_WORDS))]]
        names = [self.operand(j) for j in joints]
        for r in roots:
            if r not in self.emitted:      # status-only checks (their value feeds no joint)
                self.blocks.append(self._inline(r))
        out = [alu(A_LD, names[0])]
        for index in range(1, 5):
            out += [alu(A_LD, names[index], io=IO_OUT, iw=index - 1)]
        self.blocks.append(out + [I(io=IO_OUT, iw=4), I(io=IO_STATUS)])

    # -- operands --
    def operand(self, n):
        """A B-bus operand for ``n``: a constant, or a memory word (given its own block)."""
        if isinstance(n, int):
            return Const(n)
        if isinstance(n, Check):
            return CheckOperand(self.operand(n.args[0]))
        if n.op == Op.INPUT:
            return n.params[0]
        if n not in self.mem:
            if n.op in (Op.ROTX, Op.ROTY):
                self._rotate(n.args[0])
            else:
                name = f"v{n.id}"
                self.blocks.append(self._inline(n) + [st(name)])
                self.mem[n] = name
        return self.mem[n]

    def _cheap(self, n) -> bool:
        return isinstance(n, int) or n in self.mem or n.op in (Op.INPUT, Op.ROTX, Op.ROTY) or self.uses[n] > 1

    def acc(self, n, alone: bool = True) -> list:
        """Code leaving ``n`` in the accumulator (and raising its status events)."""
        if isinstance(n, int):
            return [alu(A_LD, Const(n))]
        if isinstance(n, Node) and (n in self.mem or n.op in (Op.INPUT, Op.ROTX, Op.ROTY) or self.uses[n] > 1
                                    or (not alone and self._heavy(n))):
            return [alu(A_LD, self.operand(n))]
        return self._inline(n)

    def _heavy(self, n) -> bool:
        """``n`` (computed in its consumer's block) runs a CORDIC, a square root or products: a
        consumer that also waits for other blocks' words would hold it back, so it gets its own."""
        if isinstance(n, int) or (isinstance(n, Node) and (n in self.mem or n.op == Op.INPUT)):
            return False
        if isinstance(n, Sop) or n.op in HEAVY:
            return True
        return self.uses[n] == 1 and any(self._heavy(d) for d in deps(n))

    def _early(self, n) -> bool:
        """``n`` is a constant or an input word (ready when the inputs are in)."""
        return isinstance(n, int) or n.op == Op.INPUT

    def _inline(self, n) -> list:
        self.emitted.add(n)
        code = self._sop(n) if isinstance(n, Sop) else LOWERING[n.op](self, n)
        for leaf in self.events.compares(n):
            code.append(_compare(leaf.event.op, leaf.event.const, _gates(leaf.gates), leaf.bit))
        return code

    # -- values: one method per operation (LOWERING) --
    def _add_sub(self, n) -> list:
        if n.op == Op.SUB and _magnitude_of(n) is not None:
            return self._abs(_magnitude_of(n))
        x, y = n.args
        if n.op == Op.ADD and isinstance(y, Node) and self._cheap(x) and not self._cheap(y):
            x, y = y, x
        return self.acc(x, self._early(y)) + [alu(A_ADD if n.op == Op.ADD else A_SUB, self.operand(y))]

    def _neg(self, n) -> list:
        return self.acc(n.args[0]) + [alu(A_NEG)]

    def _sat(self, n) -> list:
        bit, gates = self.events.saturation(n) or (0, ())
        sat = A_SATI if n.params[0] == self.ki.cfg.width else A_SATW
        return self.acc(n.args[0]) + [alu(sat, None, *_gates(gates), stat=bit)]

    def _rsr(self, n) -> list:
        halving = _halving(n)
        if halving:
            return self._halve(*halving)
        return self.acc(n.args[0]) + self.a.round_shift(n.params[0])

    def _mulc(self, n) -> list:
        return self.acc(n.args[0]) + self.a.mul_const(n.params[0], n.args[0].bits)

    def _wrap(self, n) -> list:
        return self.acc(n.args[0]) + self.a.wrap()

    def _opp(self, n) -> list:
        return self.acc(n.args[0]) + self.a.opposite()

    def _operand_only(self, n) -> list:
        raise NotImplementedError(f"{n} is read as an operand (a memory word or a B-bus operand), "
                                  "never computed in the accumulator")

    def _clip(self, n) -> list:
        x = n.args[0]
        lo, hi = n.params
        xlo, xhi = x.bounds() if isinstance(x, Sop) else (x.lo, x.hi)
        return self.acc(x) + self.a.clip(lo if lo is not None and xlo < lo else None,
                                         hi if hi is not None and xhi > hi else None)

    def _select(self, n) -> list:
        flag = n.params[0]
        if not isinstance(flag, Flag):
            raise NotImplementedError("a selection by a comparison feeds a CORDIC load only")
        a, b = n.args
        yes, no = (FLAG_SOURCE[flag.flag], 0), (FLAG_SOURCE[flag.flag], 1)
        for x, f, cond in ((a, b, yes), (b, a, no)):
            if isinstance(x, Node) and x.op == Op.NEG and x.args[0] is f:
                return self.acc(f) + [alu(A_NEG, None, cond)]
            if isinstance(x, Node) and x.op == Op.OPP and x.args[0] is f:
                return self.acc(f) + self.a.opposite(cond)
        if _add_sub(a, b):
            x, y = a.args
            return self.acc(x, self._early(y)) + [alu(A_ADD, self.operand(y), yes),
                                                  alu(A_SUB, self.operand(y), no)]
        if self._cheap(b) or not self._cheap(a):
            return self.acc(a, self._early(b)) + [alu(A_LD, self.operand(b), no)]
        return self.acc(b, self._early(a)) + [alu(A_LD, self.operand(a), yes)]

    def _halve(self, v, weight) -> list:
        """rshift_round(v * weight, 1) for a weight in {0, 2}: v where the weight is 2, else 0
        (exact either way, so the rounding does not matter): a compare and two loads instead of
        the multiplier's limb products and a rounding shift (the near-axis rule's v or 0). The
        weight is clip(e, 0, 2), positive where e is: the clip itself is not formed."""
        e = weight.args[0]
        if isinstance(e, Node) and e.op == Op.ADD and isinstance(e.args[1], int) and _doubled(e.args[0]):
            # e = s + s + c > 0 where s > floor(-c / 2) (s an integer).
            s = e.args[0].args[0]
            code = self.acc(s) + [alu(A_CMPGT, Const((-e.args[1]) // 2))]
        else:
            code = self.acc(e) + [alu(A_CMPGT, Const(0))]
        return code + [alu(A_LD, self.operand(v), (C_F, 0)), alu(A_LD, Const(0), (C_F, 1))]

    def _abs(self, v) -> list:
        """|v| as max(v, 0) - min(v, 0) (two clips, the body's magnitude of a word): a compare
        and a conditional negation."""
        return self.acc(v) + [alu(A_CMPLT, Const(0)), alu(A_NEG, None, (C_F, 0))]

    def _sqrt(self, n) -> list:
        """isqrt(x, bits): the radicand aligned to the top of the engine's register, bits / 2 digit
        steps, rounded."""
        x, bits = n.args[0], n.params[0]
        extra = 2 * self.ki.cfg.width - bits
        if extra and not isinstance(x, Sop):
            raise NotImplementedError("a narrow radicand must be a sum of products")
        code = self._sop(x, extra) if isinstance(x, Sop) else self.acc(x)
        digits = bits // 2          # two per clock, the odd one alone
        return (code + [I(sq=Q_LOAD)] + [I(sq=Q_STEP2)] * (digits // 2) + [I(sq=Q_STEP)] * (digits % 2)
                + sqrt_round(self.a))

    def _atan2(self, n) -> list:
        """Operand loads (a selection by a comparison: F, then the other operand where not F), the
        vectoring, the angle; the zero vector's status events while the latch is held."""
        code, loads = [], []
        if len({v.params[0] for v in n.args if _cond_sel(v)}) > 1:
            raise NotImplementedError("the two operands of an atan2 selected by different conditions")
        for v, op in zip(n.args[::-1], (K_LDXG, K_LDYG)):
            if _cond_sel(v):
                value, cmp, const, truth = _compare_of(v.params[0])
                if not code:
                    code = self.acc(value) + [alu(A_CMPGT if cmp == ">" else A_CMPLT, Const(const))]
                loads += [I(cop=op, **_op(self.operand(v.args[1]))),
                          I((C_F, int(not truth)), cop=op, **_op(self.operand(v.args[0])))]
            else:
                loads += [I(cop=op, **_op(self.operand(v)))]
        zeros = [(leaf.bit, _gates(leaf.gates)) for leaf in self.events.zeros(n)]
        merged = zeros[0][0] if len(zeros) == 1 and not zeros[0][1] else 0
        tail = [] if merged else [alu(A_NOP, None, (C_ZERO, 0), *gates, stat=bit) for bit, gates in zeros]
        return code + loads + self.a.atan2_body() + self.a.atan2_angle(merged, tail)

    def _rotate(self, r):
        x, y, angle = r.args
        self.emitted.add(r)
        bit, gates = self.events.saturation(r) or (0, ())
        names = (f"v{r.id}x", f"v{r.id}y")
        self.blocks.append(self.a.rotate(self.operand(x), self.operand(y), self.operand(angle),
                                         *names, f"v{r.id}g", bit, _gates(gates)))
        for axis, node in r.g.outputs_of(r).items():
            self.mem[node] = names[axis == "y"]

    # -- exact sums --
    def _sop(self, s: Sop, extra: int = 0) -> list:
        """acc = sum of ±a*b << shift (+ const), all shifted up by ``extra``; a negative term
        goes first (the multiplier negates only the first product)."""
        terms = []
        for a, b, neg, shift in s.terms:
            if isinstance(b, int) and neg:
                b, neg = -b, False
            terms.append((a, b, neg, shift + extra))
        if not terms:
            return [alu(A_LD, Const(s.const << extra))]
        terms.sort(key=lambda t: not t[2])
        if sum(t[2] for t in terms) > 1:
            raise NotImplementedError("more than one negative product in a sum")
        lead = [alu(A_LD, Const(s.const << extra))] if s.const and not terms[0][2] else []
        code = lead + self.a.products([(self.operand(a), _bits(a, self.ki), self.operand(b),
                                        _bits(b, self.ki), neg, shift) for a, b, neg, shift in terms],
                                      first=not lead)
        if s.const and not lead:
            code += [alu(A_ADD, Const(s.const << extra))]
        return code


def _doubled(n) -> bool:
    return isinstance(n, Node) and not isinstance(n, Sop) and n.op == Op.ADD and n.args[0] is n.args[1]


def _magnitude_of(n):
    """v if ``n`` is clip(v, 0, hi) - clip(v, lo, 0) with v within [lo, hi] (so |v|), else None."""
    a, b = n.args
    if not all(isinstance(c, Node) and not isinstance(c, Sop) and c.op == Op.CLIP for c in (a, b)):
        return None
    v = a.args[0]
    if b.args[0] is not v or a.params[0] != 0 or b.params[1] != 0 or None in (a.params[1], b.params[0]):
        return None
    lo, hi = v.bounds() if isinstance(v, Sop) else (v.lo, v.hi)
    return v if b.params[0] <= lo and hi <= a.params[1] else None


def _even(n) -> bool:
    """``n`` is even for every input (a sum of a value with itself, of evens, an even constant)."""
    if isinstance(n, int):
        return n % 2 == 0
    if not isinstance(n, Node) or isinstance(n, Sop) or n.op not in (Op.ADD, Op.SUB, Op.NEG):
        return False
    if n.op in (Op.ADD, Op.SUB) and n.args[0] is n.args[1]:
        return True
    return all(_even(v) for v in n.args)


def _halving(n):
    """(v, weight) if ``n`` is rshift_round(v * weight, 1) with weight a clip to [0, 2] of an
    even value (so 0 or 2), else None."""
    s = n.args[0]
    if n.params[0] != 1 or not isinstance(s, Sop) or s.const or len(s.terms) != 1:
        return None
    for v, w in (s.terms[0][:2], s.terms[0][1::-1]):
        if (s.terms[0][2:] == (False, 0) and isinstance(w, Node) and not isinstance(w, Sop)
                and w.op == Op.CLIP and w.params == (0, 2) and _even(w.args[0])):
            return v, w
    return None


def _bits(v, ki) -> int:
    if isinstance(v, int):
        return v.bit_length() + 1
    if isinstance(v, Check):
        return ki.cfg.width
    return v.bits


def _compare(op, const, gates, bit) -> dict:
    return alu(A_CMPGT if op == ">" else A_CMPLT, Const(const), *gates, stat=bit)


#: The engine code of each operation (a method of :class:`Lower`). ``WORD``: the input words are
#: loaded by the first block, and the body reads them as ``INPUT``s; ``CHECK``, ``INPUT``,
#: ``ROTX`` and ``ROTY`` are operands (:meth:`Lower.operand`: a check word of the B bus, an input
#: word, a rotation's memory word); a ``ROT`` is its own block (:meth:`Lower._rotate`).
LOWERING = require_every_op({
    Op.WORD: Lower._operand_only, Op.INPUT: Lower._operand_only, Op.CHECK: Lower._operand_only,
    Op.ROT: Lower._operand_only, Op.ROTX: Lower._operand_only, Op.ROTY: Lower._operand_only,
    Op.NEG: Lower._neg, Op.ADD: Lower._add_sub, Op.SUB: Lower._add_sub, Op.SAT: Lower._sat,
    Op.RSR: Lower._rsr, Op.MULC: Lower._mulc, Op.WRAP: Lower._wrap, Op.OPP: Lower._opp,
    Op.SEL: Lower._select, Op.CLIP: Lower._clip, Op.ATAN2: Lower._atan2, Op.SQRT: Lower._sqrt,
}, "the sequenced engine's lowering")
