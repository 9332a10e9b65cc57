"""Multipliers of the ik5r datapaths, built from 17 x 17 partial products (one 18 x 18 DSP each):
:func:`add_products` appends the stages of one or more parallel multipliers to a
:class:`~ik5r.hdl.datapath.stages.Datapath`, all partial products at once and an adder tree. A
partial product of registered operands is a :class:`Product`, which the pipelined build with
``dsp="ecp5"`` maps to a ``MULT18X18D``."""

from __future__ import annotations

from amaranth.hdl import Const, Mux, Shape, Signal, Value, ValueCastable, signed, unsigned

from .ecp5 import MULT_BITS, mult18x18d
from .expr import drop, extend

__all__ = ["LIMB_BITS", "LUT_ROWS", "NARROW_ROWS", "DspBudget", "Product", "add_products"]

#: Operand slice width of a partial product: 17 x 17 unsigned (18 x 18 signed at the top limb)
#: fits one ECP5 MULT18X18D.
LIMB_BITS = 17
assert LIMB_BITS + 1 == MULT_BITS


def _limbs(shape: Shape):
    """Bit ranges (lo, hi, signed) of LIMB_BITS-wide slices of an operand; top one keeps sign."""
    width = shape.width
    ranges = []
    for lo in range(0, width, LIMB_BITS):
        hi = min(lo + LIMB_BITS, width)
        ranges.append((lo, hi, shape.signed and hi == width))
    return ranges


def _slice(value, lo, hi, is_signed):
    part = Value.cast(value)[lo:hi]
    return part.as_signed() if is_signed else part


def _limb18(value, lo, hi, is_signed):
    """Bits [lo, hi) of ``value`` as a ``signed(LIMB_BITS + 1)`` multiplier operand."""
    part = _slice(value, lo, hi, is_signed)
    return extend(part, LIMB_BITS + 1).as_signed()


class Product(ValueCastable):
    """One partial product ``(a[a_lo:a_hi] * b_part) << shift`` of registered operands; ``b_part``
    is a non-negative constant below 2**LIMB_BITS or a ``(b, lo, hi, signed)`` slice. As a value it
    is that expression; :meth:`map_ecp5` builds it as a ``MULT18X18D`` instead."""

    def __init__(self, a, a_range, b_part, shift):
        self.a, self.a_range, self.b_part, self.shift = a, a_range, b_part, shift
        self._value = (_slice(a, *a_range) * self._b_value()).shift_left(shift)

    def as_value(self):
        return self._value

    def shape(self):
        return self._value.shape()

    def _b_value(self):
        if isinstance(self.b_part, int):
            return Const(self.b_part, unsigned(max(self.b_part.bit_length(), 1)))
        return _slice(self.b_part[0], *self.b_part[1:])

    def rows(self) -> int:
        """Rows of its shift-and-add form: the narrower operand's bits (a constant's set bits)."""
        a_bits = self.a_range[1] - self.a_range[0]
        if isinstance(self.b_part, int):
            return min(a_bits, bin(self.b_part).count("1"))
        return min(a_bits, self.b_part[2] - self.b_part[1])

    def lut_value(self) -> Value:
        """The same product as a balanced sum of :meth:`rows` shifted rows: logic with no
        multiplier cell, so Yosys cannot map it to a DSP."""
        a_part = _slice(self.a, *self.a_range)
        b = self.b_part
        if isinstance(b, int) and bin(b).count("1") <= len(a_part):
            rows = [a_part.shift_left(bit) for bit in range(b.bit_length()) if b >> bit & 1]
        else:
            b_value = self._b_value()
            narrow, wide = (b_value, a_part) if len(b_value) <= len(a_part) else (a_part, b_value)
            rows = [Mux(narrow[bit], wide, 0).shift_left(bit) for bit in range(len(narrow))]
            if narrow.shape().signed:      # two's complement: the top bit weighs -2**(n-1)
                rows[-1] = -rows[-1]
        while len(rows) > 1:
            rows = [rows[i] + rows[i + 1] if i + 1 < len(rows) else rows[i] for i in range(0, len(rows), 2)]
        return rows[0].shift_left(self.shift) if rows else Const(0, 1)

    def map_ecp5(self, m, name, target, loaded) -> bool:
        """Drive ``target`` from a ``MULT18X18D`` with input and output registers (always
        enabled, as the pipeline), fed by what the previous stage's registers ``a`` (and ``b``)
        were loaded with; False (nothing built) when an operand is not such a register."""
        if id(self.a) not in loaded:
            return False
        a_reg, a_next = loaded[id(self.a)]
        a_src = Signal(a_reg.shape(), name=f"{name}_a")
        m.d.comb += a_src.eq(a_next)
        if isinstance(self.b_part, int):
            b18 = Const(self.b_part, signed(LIMB_BITS + 1))
        else:
            b, lo, hi, is_signed = self.b_part
            if id(b) not in loaded:
                return False
            b_reg, b_next = loaded[id(b)]
            b_src = Signal(b_reg.shape(), name=f"{name}_b")
            m.d.comb += b_src.eq(b_next)
            b18 = _limb18(b_src, lo, hi, is_signed)
        a18 = _limb18(a_src, *self.a_range)
        product = mult18x18d(m, name, a18, b18)
        m.d.comb += target.eq(product.shift_left(self.shift))
        return True


#: A partial product of at most this many shift-and-add rows (a top limb of a bit or two, a
#: constant of two set bits) is built in LUTs: one adder level, no more delay than a DSP and no
#: DSP spent on 2 of its 18 x 18 bits.
LUT_ROWS = 2

#: A term of at most this many rows (a top limb of a few bits) is split in two LUT terms of at
#: most :data:`LUT_ROWS` rows where the adder tree has room for the extra term
#: (:func:`_split_narrow`); where it has not, it takes a DSP: two adder levels in one stage were
#: the critical path of the q32w core on the ECP5-85k.
NARROW_ROWS = 4


class DspBudget:
    """Which partial products of a pipelined ECP5 build get a ``MULT18X18D``, in build order:
    never one of at most :data:`LUT_ROWS` rows; the others while fewer than ``max_dsp`` (no cap:
    None) are taken, the rest in LUTs (:meth:`Product.lut_value`, one stage of shift-and-add)."""

    def __init__(self, max_dsp: int | None = None):
        if max_dsp is not None and (not isinstance(max_dsp, int) or max_dsp < 0):
            raise ValueError(f"max_dsp must be a non-negative int or None, got {max_dsp!r}")
        self.max_dsp, self.used = max_dsp, 0

    def wants_dsp(self, product: Product) -> bool:
        if product.rows() <= LUT_ROWS:
            return False
        if self.max_dsp is not None and self.used >= self.max_dsp:
            return False
        self.used += 1
        return True


def add_products(dp, prefix: str, specs, *, parallel=None, drop_keys=()):
    """Append the stages of one or more parallel multipliers ``a * b`` to ``dp``.

    ``specs``: list of ``(a_of, a_shape, b, out_key)``; ``a_of(state)`` gives operand a (which
    must fit ``a_shape``); ``b`` is a non-negative int constant or ``(b_of, b_shape)``.

    Stage 1 registers the operands (in their shapes), stage 2 forms the LIMB_BITS x LIMB_BITS
    partial products (one DSP each, nothing else in the stage), then the ECP5 build's
    ``dsp_output_regs`` register stages (:func:`_output_regs`); each further stage adds pairs of
    partial sums (one adder level), until one sum per multiplier is left under ``out_key``.
    ``parallel(state) -> dict`` adds other work to stage 1 (e.g. a rounding), and ``drop_keys``
    are removed from the state at stage 1. Returns the number of stages.
    """
    # A square (b the same expression as a): one operand register, each cross term once.
    specs = [(a_of, a_shape, SQUARE if _is_square(a_of, a_shape, b) else b, out_key)
             for a_of, a_shape, b, out_key in specs]
    trees = [(a_of, out_key, _partial_products(prefix, index, a_shape, b))
             for index, (a_of, a_shape, b, out_key) in enumerate(specs)]
    # Stage 1 registers the operands: a register next to the DSPs, so that the stage holding a
    # DSP has only the DSP's own delay (the DSP registers themselves are not inferred).
    for index, (_, a_shape, b, _) in enumerate(specs):
        dp.declare(**{f"{prefix}{index}_a": a_shape})
        if isinstance(b, tuple):
            dp.declare(**{f"{prefix}{index}_b": b[1]})
    dp.add(f"{prefix}_op", _operands_stage(prefix, [(a_of, b) for a_of, _, b, _ in specs],
                                           parallel, drop_keys))
    dp.add(f"{prefix}_mul", _products_stage(prefix, trees))
    holds = _output_regs(dp, trees)
    for index in range(holds):
        dp.add(f"{prefix}_hold{index}", dict)
    return 2 + holds + _add_adder_tree(dp, prefix, trees)


def _output_regs(dp, trees) -> int:
    """Register stages the ECP5 build adds after the partial products (``dsp_output_regs`` of
    its adders): a ``MULT18X18D`` sits in a DSP row, and the route from its output register to
    the first adder of its sum is long (the critical path of the q32w core's ECP5-85k record);
    a fabric register lets the placer put a flip-flop next to the DSP and the adder next to the
    flip-flop. None where no term can take a DSP (:class:`DspBudget`: at most
    :data:`LUT_ROWS` rows)."""
    if not any(_term_rows(a_range, b_part) > LUT_ROWS for _, _, terms in trees for _, _, a_range, b_part in terms):
        return 0
    return dp.adders.dsp_output_regs


#: The ``b`` of a multiplier that squares its ``a`` (see :func:`_is_square`).
SQUARE = "square"


class _Probe(dict):
    """A state whose every key reads as a signal of its own (for :func:`_is_square`)."""

    def __missing__(self, key):
        self[key] = Signal(signed(64), name=f"probe{len(self)}")
        return self[key]


def _is_square(a_of, a_shape, b) -> bool:
    """Whether ``b`` is ``(b_of, shape)`` with ``b_of`` the same expression of the state as
    ``a_of``, in the same shape: the product is then a square. Anything that cannot be told
    (an operand function that fails on the probe) is not a square."""
    if not isinstance(b, tuple) or Shape.cast(a_shape) != Shape.cast(b[1]):
        return False
    probe = _Probe()
    try:
        a_value, b_value = a_of(probe), b[0](probe)
        return a_value is b_value or repr(Value.cast(a_value)) == repr(Value.cast(b_value))
    except Exception:       # noqa: BLE001 - an operand function that needs a real state
        return False


def _partial_products(prefix, index, a_shape, b) -> list:
    """The terms ``(key, shift, a_range, b_part)`` of one multiplier: :func:`_limb_terms`, the
    narrow ones split (:func:`_split_narrow`)."""
    return _split_narrow(_limb_terms(prefix, index, a_shape, b))


def _limb_terms(prefix, index, a_shape, b) -> list:
    """The products of one multiplier's limbs as terms ``(key, shift, a_range, b_part)``. A
    square's cross terms (limbs i < j, equal to limbs j, i) come once, doubled by one more bit of
    shift."""
    a_shape, terms = Shape.cast(a_shape), []
    if b == SQUARE:
        limbs = _limbs(a_shape)
        for i, (a_lo, a_hi, a_signed) in enumerate(limbs):
            for b_lo, b_hi, b_signed in limbs[i:]:
                terms.append((f"{prefix}{index}_p{len(terms)}", a_lo + b_lo + (b_lo != a_lo),
                              (a_lo, a_hi, a_signed), (SQUARE, b_lo, b_hi, b_signed)))
    elif isinstance(b, int):
        if b < 0:
            raise ValueError("constant multiplier must be non-negative")
        for a_lo, a_hi, a_signed in _limbs(a_shape):
            for b_lo in range(0, max(b.bit_length(), 1), LIMB_BITS):
                b_part = (b >> b_lo) & ((1 << LIMB_BITS) - 1)
                if b_part:
                    terms.append((f"{prefix}{index}_p{len(terms)}", a_lo + b_lo,
                                  (a_lo, a_hi, a_signed), b_part))
    else:
        b_of, b_shape = b
        for a_lo, a_hi, a_signed in _limbs(a_shape):
            for b_lo, b_hi, b_signed in _limbs(Shape.cast(b_shape)):
                terms.append((f"{prefix}{index}_p{len(terms)}", a_lo + b_lo,
                              (a_lo, a_hi, a_signed), (b_of, b_lo, b_hi, b_signed)))
    return terms


def _term_rows(a_range, b_part) -> int:
    """A term's rows as :meth:`Product.rows` counts them."""
    a_bits = a_range[1] - a_range[0]
    if isinstance(b_part, int):
        return min(a_bits, bin(b_part).count("1"))
    return min(a_bits, b_part[2] - b_part[1])


def _levels(count: int) -> int:
    return (count - 1).bit_length()


def _split_narrow(terms) -> list:
    """Each term of more than :data:`LUT_ROWS` and at most :data:`NARROW_ROWS` rows split in two
    (:func:`_halves`), where the adder tree needs no more levels for them (no more latency)."""
    narrow = [t for t in terms if LUT_ROWS < _term_rows(t[2], t[3]) <= NARROW_ROWS]
    if not narrow or _levels(len(terms) + len(narrow)) > _levels(len(terms)):
        return terms
    out = []
    for key, shift, a_range, b_part in terms:
        if not LUT_ROWS < _term_rows(a_range, b_part) <= NARROW_ROWS:
            out.append((key, shift, a_range, b_part))
            continue
        out += [(f"{key}{half}", *part) for half, part in zip("lh", _halves(shift, a_range, b_part))]
    return out


def _halves(shift, a_range, b_part):
    """Two terms summing to one: the narrow operand's two low rows and the rest."""
    a_lo, a_hi, a_signed = a_range
    if isinstance(b_part, int) and bin(b_part).count("1") <= a_hi - a_lo:
        low = b_part & -b_part
        low |= (b_part ^ low) & -(b_part ^ low)
        return [(shift, a_range, low), (shift, a_range, b_part ^ low)]
    if isinstance(b_part, int) or a_hi - a_lo <= b_part[2] - b_part[1]:
        return [(shift, (a_lo, a_lo + 2, False), b_part), (shift + 2, (a_lo + 2, a_hi, a_signed), b_part)]
    src, b_lo, b_hi, b_signed = b_part
    return [(shift, a_range, (src, b_lo, b_lo + 2, False)), (shift + 2, a_range, (src, b_lo + 2, b_hi, b_signed))]


def _operands_stage(prefix, operands, parallel, drop_keys):
    """Stage 1: the operands ``{prefix}{index}_a`` (and ``_b``) of ``operands`` ``[(a_of, b)]``,
    then ``parallel``'s work; ``drop_keys`` dropped."""
    def run(state):
        out = drop(state, *drop_keys)
        for index, (a_of, b) in enumerate(operands):
            out[f"{prefix}{index}_a"] = a_of(state)
            if isinstance(b, tuple):
                out[f"{prefix}{index}_b"] = b[0](state)
        if parallel is not None:
            out.update(parallel(state))
        return out
    return run


def _products_stage(prefix, trees):
    def run(state):
        out = dict(state)
        for index, (_, out_key, terms) in enumerate(trees):
            a = state[f"{prefix}{index}_a"]
            b = state.get(f"{prefix}{index}_b", a)     # a square: a itself
            out = drop(out, f"{prefix}{index}_a", f"{prefix}{index}_b")
            if not terms:
                out[out_key] = Const(0, 1)
            for key, shift, a_range, b_part in terms:
                if not isinstance(b_part, int):
                    b_part = (b,) + b_part[1:]
                # A single product is the result: it keeps its weight; terms of a sum get theirs
                # in the adder tree.
                out[key] = Product(a, a_range, b_part, shift if len(terms) == 1 else 0)
            if len(terms) == 1:
                out[out_key] = out.pop(terms[0][0])
        return out
    return run


def _adder_level(plan):
    """One adder level: each group of (key, shift) terms of ``plan`` summed at its lowest weight."""
    def run(state):
        out = dict(state)
        for out_key, groups in plan.items():
            sums = []
            for group in groups:
                base = min(shift for _, shift in group)
                total = None
                for key, shift in group:
                    term = Value.cast(state[key]).shift_left(shift - base)
                    del out[key]
                    total = term if total is None else total + term
                sums.append((f"{group[0][0]}s", base, total))
            if len(sums) == 1:
                _, base, total = sums[0]
                out[out_key] = total.shift_left(base)
            else:
                out.update({key: total for key, _, total in sums})
        return out
    return run


def _add_adder_tree(dp, prefix, trees) -> int:
    """Adder tree: each level adds adjacent (by weight) pairs of terms; an odd one passes
    through. Returns the number of levels."""
    pending = {out_key: [(key, shift) for key, shift, _, _ in terms]
               for _, out_key, terms in trees if len(terms) > 1}
    depth = 0
    while pending:
        plan = {}
        for out_key, terms in pending.items():
            terms = sorted(terms, key=lambda term: term[1])
            plan[out_key] = [terms[pair:pair + 2] for pair in range(0, len(terms), 2)]
        dp.add(f"{prefix}_sum{depth}", _adder_level(plan))
        depth += 1
        pending = {out_key: [(f"{group[0][0]}s", min(shift for _, shift in group))
                             for group in groups]
                   for out_key, groups in plan.items() if len(groups) > 1}
    return depth

