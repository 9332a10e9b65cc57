"""Pure expression helpers of the ik5r datapaths: shifts, one-adder add-or-subtract, rounding,
saturation, leading zeros, table lookups. Each builds an Amaranth expression and adds no
statement, so a stage function may call it any number of times (see :mod:`.datapath`).
"""

from __future__ import annotations

from amaranth.hdl import Cat, Const, Mux, Value, signed, unsigned

from .ecp5 import ccu2c_add_sub

__all__ = ["asr", "extend", "add_sub", "rshift_round", "saturate", "leading_zeros", "select", "onehot_select",
           "table_entry", "drop"]


def asr(value, amount):
    """``value >> amount``: arithmetic for a signed value, by an int or an unsigned Value."""
    value = Value.cast(value)
    if isinstance(amount, int):
        return value.shift_right(amount)
    return value >> amount


def asr_radix4(value, amount):
    """``value >> amount`` (arithmetic for a signed value) by an unsigned Value, as a barrel
    shifter of 4-way stages (two amount bits each: one LUT5 level on an ECP5), most significant
    first: the long shifts fill the top with copies of the sign bit, which the later stages'
    muxes select among and Yosys folds (fewer LUTs than least significant first for the
    compact core's CORDIC shifters, at the same Fmax: the commit that made the choice)."""
    value = Value.cast(value)
    for lsb in reversed(range(0, len(amount), 2)):
        bits = amount[lsb:lsb + 2]
        value = select([value.shift_right(j << lsb) for j in range(1 << len(bits))], bits)
    return value


def extend(value, width):
    """``value`` sign- (or zero-) extended to ``width`` bits, as raw bits."""
    fill = value[-1] if value.shape().signed else Const(0, 1)
    return Cat(value, fill.replicate(width - len(value)))


def add_sub(a, b, subtract, *, chains: list | None = None):
    """``a - b`` if ``subtract`` else ``a + b``, with ONE adder (not two and a mux).

    ``(a << 1 | s) + ((b ^ s...s) << 1 | s)`` has ``a + (b ^ s...s) + s`` above its LSB: the
    carry-in is folded into the extra LSB. Exact: the result is a ``signed`` value wide enough
    for any ``a +- b``.

    Yosys maps the XOR to a LUT of its own in front of each carry cell (one LUT level and one
    route more than an adder: the CORDIC direction's path, and half of a micro-rotation's LUTs).
    Given a list ``chains`` (the ECP5 mapping, :class:`~ik5r.hdl.datapath.stages.Ecp5Adders`), the same
    sum is an ECP5 ``CCU2C`` chain whose own LUTs take ``subtract`` as a third input
    (:func:`~ik5r.hdl.datapath.ecp5.ecp5_add_sub_verilog`), appended to ``chains`` for the caller to add
    to its module, as Yosys's own ``$alu`` mapping does with its B-invert input, which it never
    infers from this form. A constant ``subtract`` is always the generic adder.
    """
    a, b, subtract = Value.cast(a), Value.cast(b), Value.cast(subtract)
    width = max(len(a) + (not a.shape().signed), len(b) + (not b.shape().signed)) + 1
    if chains is not None and not isinstance(subtract, Const):
        return ccu2c_add_sub(extend(a, width), extend(b, width), subtract, chains)
    inverted = extend(b, width) ^ subtract.replicate(width)
    total = Cat(subtract, extend(a, width)) + Cat(subtract, inverted)
    return total[1:width + 1].as_signed()


def rshift_round(value, shift: int, nearest: bool):
    """``value * 2**-shift`` by a constant shift, rounded half up (nearest) or floored.

    Exactly ``fixedpoint.rshift_round``: one adder when ``nearest`` and ``shift > 0``, else wiring.
    """
    value = Value.cast(value)
    if shift <= 0:
        return value.shift_left(-shift)
    if nearest:
        value = value + (1 << (shift - 1))
    return value.shift_right(shift)


def saturate(value, width: int):
    """Clip ``value`` to the signed ``width``-bit range; returns ``(word, saturated)``.

    Pure logic (no comparator): the value fits iff its bits above ``width - 1`` are all copies
    of the sign. Exactly ``fixedpoint.saturate``.
    """
    value = Value.cast(value)
    # A signed value of up to width bits fits; an unsigned one only below width bits (at width
    # bits its top bit is a magnitude bit, beyond the signed range).
    if len(value) < width or (len(value) == width and value.shape().signed):
        return value, Const(0, 1)
    if not value.shape().signed:
        value = Cat(value, Const(0, 1)).as_signed()
    top = value[width - 1:]
    negative = value[-1]
    over = ~negative & top.any()
    under = negative & ~top.all()
    word_max = (1 << (width - 1)) - 1
    word_min = -(1 << (width - 1))
    clipped = Mux(over, Const(word_max, signed(width)),
                  Mux(under, Const(word_min, signed(width)), value[:width].as_signed()))
    return clipped, over | under


def _lzc_tree(value):
    """(all zero, leading zero count) of a power-of-two-wide value, as a balanced tree."""
    if len(value) == 1:
        return ~value[0], Const(0, 0)
    half = len(value) // 2
    zero_lo, count_lo = _lzc_tree(value[:half])
    zero_hi, count_hi = _lzc_tree(value[half:])
    count = Mux(zero_hi, Cat(count_lo, Const(1, 1)), Cat(count_hi, Const(0, 1)))
    return zero_hi & zero_lo, count


def leading_zeros(value):
    """Number of leading zero bits of an unsigned value of width n (n when it is zero).

    A tree of log2(n) mux levels. The value is padded on the LSB side with ``1 0 ... 0`` up to a
    power of two, so the padded value is never zero and its count is the answer.
    """
    value = Value.cast(value)
    size = 1
    while size < len(value) + 1:
        size *= 2
    pad = size - len(value)
    _, count = _lzc_tree(Cat(Const(1 << (pad - 1), pad), value))
    return count


def select(options, index):
    """``options[index]`` for an unsigned Value ``index``: a balanced tree of 2-way muxes on the
    index bits (0 past the end of ``options``).

    Not ``Array(...)[index]``: an Array becomes a ``casez`` in an ``always @*`` block in the
    Verilog, which reads only the (initialised) step register. Under IEEE 1800 semantics (Icarus
    -g2012, as cocotb builds) a declaration initialiser is no event, so that block does not run
    before the step first changes and the entry of step 0 is X for the first item after time 0.
    A mux is a continuous assignment: defined from time 0 on every simulator.
    """
    index = Value.cast(index)
    # Entries past what the index can encode are unreachable (e.g. a limb the program never picks).
    level = list(options)[:1 << len(index)]
    level += [Const(0, 1)] * ((1 << len(index)) - len(level))
    for bit in range(len(index)):
        level = [Mux(index[bit], level[j + 1], level[j]) for j in range(0, len(level), 2)]
    return level[0]


def onehot_select(options, index):
    """``options[index]`` for an unsigned Value ``index`` as an AND-OR of ``index == i`` terms
    (0 past the end of ``options``): where the index is a register and the options are shifted
    copies of one value (sparse bits), Yosys packs it in fewer LUTs than :func:`select`'s tree
    (the compact core's product register: the commit that made the choice)."""
    index = Value.cast(index)
    total = Const(0, 1)
    for i, option in enumerate(list(options)[:1 << len(index)]):
        total = total | Mux(index == i, option, 0)
    return total


def table_entry(table, index):
    """``table[index]`` for a constant table: a constant for an int index, else :func:`select`
    over the entries in the union of their shapes (0 past the end of the table)."""
    if isinstance(index, int):
        return Const(table[index])
    shapes = [Const(entry).shape() for entry in table]
    if any(s.signed for s in shapes):
        shape = signed(max(s.width + (not s.signed) for s in shapes))
    else:
        shape = unsigned(max(s.width for s in shapes))
    return select([Const(entry, shape) for entry in table], index)


def drop(state, *keys):
    """A copy of a state dictionary without ``keys`` (a traced state's copy stays traced: see
    :meth:`~ik5r.hdl.datapath.stages.Datapath.check`)."""
    out = {key: value for key, value in state.items() if key not in keys}
    derive = getattr(state, "derive", None)
    return out if derive is None else derive(out)
