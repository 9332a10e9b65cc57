"""The units of the sequenced engine (:class:`.engine.SeqEngine`): each a function adding one
unit's registers and logic to the engine's module, all stepping on ``run`` from the executing
instruction (``ins``: a view of its :func:`.isa.word_layout` word; ``dec``: controls decoded a
clock early).
"""

from __future__ import annotations

from amaranth.hdl import Cat, Const, Mux, Signal, signed

from ik5r.core import status as S
from ik5r.core.fxconfig import CHECK_BITS
from ik5r.core.modes import Dsp

from . import isa as X
from ..datapath.ecp5 import MULT_BITS, mult18x18d
from ..datapath.expr import add_sub, asr_radix4, onehot_select, saturate, select

STATUS_BITS = S.FIXED_WIDTH
#: Multiplier operand bits: a 16-bit signed limb or a check word.
_FACTOR_BITS = max(16, CHECK_BITS)


def registers(w, dsp: str = Dsp.GENERIC):
    """The engine's unit registers by name (the limb registers in the DSPs with ``dsp`` ecp5)."""
    regs = {
        "flag": Signal(name="flag"), "zero": Signal(name="zero"), "back": Signal(name="back"),
        "down": Signal(name="down"), "roll": Signal(name="roll"),
        "status": Signal(w.status, name="status"), "tag": Signal(max(1, w.tag), name="tag"),
        "cx": Signal(signed(w.xy), name="cx"), "cy": Signal(signed(w.xy), name="cy"),
        "cz": Signal(signed(w.z), name="cz"),
        "ma": Signal(signed(w.operand), name="ma"), "mb": Signal(signed(w.operand), name="mb"),
        "la": Signal(signed(_FACTOR_BITS), name="la"), "lb": Signal(signed(b_factor_bits(w)), name="lb"),
        "prod": Signal(signed(w.acc), name="prod"),
        "rad": Signal(w.radicand, name="rad"), "root": Signal(w.radicand // 2 + 1, name="root"),
        "rem": Signal(w.radicand // 2 + 2, name="rem"),
    }
    if dsp == Dsp.ECP5:
        del regs["la"], regs["lb"]
    return regs

def alu(m, ins, dec, acc, bus, mem_q, cond, regs, run, w, acc_shifts, pose_regs=None):
    """The accumulator ALU: the adder, compares, shifts (by ``acc_shifts``), saturations, F and
    the status bits (of the event's pose, ``pose_regs``, in a program of several)."""
    # The adder: its right operand a one-hot AND-OR of its own few sources (not the B bus),
    # inverted for a subtraction; the carry in enters as a bit below the operands (one chain).
    right = Signal(signed(w.acc), name="alu_right")
    m.d.comb += right.eq(Mux(dec["right_product"], regs["prod"], 0) | Mux(dec["right_acc"], acc, 0)
                         | Mux(dec["right_mem"], mem_q, 0) | Mux(dec["right_root"], regs["root"], 0))
    left = Mux(dec["left_zero"], 0, acc)
    wide = Signal(w.acc + 1, name="alu_wide")
    m.d.comb += wide.eq(Cat(dec["carry"], left)
                        + Cat(dec["carry"], (right ^ dec["sub"].replicate(w.acc))[:w.acc]))
    total = Signal(signed(w.acc), name="alu_sum")
    m.d.comb += total.eq(wide[1:])
    # A compare's result: the sign of acc - b (CMPLT) or of acc - b - 1, inverted (CMPGT).
    result = Signal(name="alu_compare")
    m.d.comb += result.eq(total[-1] ^ dec["gt"])
    sat_i, clip_i = saturate(acc, w.internal)
    sat_w, clip_w = saturate(acc, w.word)
    # Everything but the sum is ready early: the sum (and the compare) enter at the last
    # mux of the accumulator, the F flag and the status bits.
    early = Signal(signed(w.acc), name="alu_early")
    # A compare's event is its result (under the condition); other ops' events are early: the
    # condition (an LD or a shift raises its status bit too: the zero vector's angle load), and
    # for a saturation also its clip.
    other_event = Signal(name="alu_event")
    m.d.comb += other_event.eq(cond)
    with m.Switch(ins.alu):
        with m.Case(X.A_LD):
            m.d.comb += early.eq(bus)
        for op, bits in zip(X.SHIFTS, acc_shifts):
            with m.Case(op):
                m.d.comb += early.eq(acc.shift_right(bits))
        with m.Case(X.A_SATI):
            m.d.comb += [early.eq(sat_i), other_event.eq(cond & clip_i)]
        with m.Case(X.A_SATW):
            m.d.comb += [early.eq(sat_w), other_event.eq(cond & clip_w)]
        with m.Default():       # the event restated: a case for every value (lint-clean)
            m.d.comb += [early.eq(sat_w), other_event.eq(cond)]
    on_compare = Mux(dec["cmp"] & cond, ins.stat, 0)
    on_other = Mux(~dec["cmp"] & other_event, ins.stat, 0)
    with m.If(run):
        with m.If(dec["sat"] | (dec["acc_cond"] & cond)):
            m.d.sync += acc.eq(Mux(dec["acc_total"], total, early))
        with m.If(dec["cmp"] & cond):
            m.d.sync += regs["flag"].eq(result)
        with m.Elif(ins.alu == X.A_SETF):
            m.d.sync += regs["flag"].eq(cond)
        # Status bits reach the register a clock after their event.
        pending = Signal(w.status, name="status_pending")
        m.d.sync += pending.eq(Mux(result, on_compare, 0) | on_other)
        if pose_regs:
            pose_regs.status(m, ins, pending)
        else:
            m.d.sync += regs["status"].eq(Mux(ins.io == X.IO_FLAGS, 0, regs["status"] | pending))

def cordic(m, ins, dec, shift, bus, cond, step, regs, run, w):
    """The CORDIC unit: loads, quarter turns, normalising shifts, one micro-rotation a clock."""
    op = ins.cop
    x, y, z = regs["cx"], regs["cy"], regs["cz"]
    quarter = dec["quarter"]
    ccw = Mux(dec["vectoring"], y[-1], ~z[-1])
    x_next = add_sub(Mux(quarter, 0, x), asr_radix4(y, shift[1]), ccw)
    y_next = add_sub(Mux(quarter, 0, y), asr_radix4(x, shift[0]), ~ccw)
    z_next = add_sub(z, step, ccw)
    ones_abs = Mux(y[-1], ~y, y)
    v = (x | ones_abs).as_unsigned()
    top = w.internal - 1 + w.cordic_guard
    go = Mux(op == X.K_COARSE, x[-1], Mux(op == X.K_QROT, regs["flag"], 1))
    with m.If(run), m.Switch(op):
        with m.Case(X.K_LDX, X.K_LDXG):
            with m.If(cond):
                m.d.sync += x.eq(Mux(op == X.K_LDXG, bus.shift_left(w.cordic_guard), bus))
                with m.If(op == X.K_LDXG):
                    m.d.sync += z.eq(0)
        with m.Case(X.K_LDY, X.K_LDYG):
            with m.If(cond):
                m.d.sync += y.eq(Mux(op == X.K_LDYG, bus.shift_left(w.cordic_guard), bus))
        with m.Case(X.K_LDZA):
            with m.If(cond):
                m.d.sync += z.eq(bus.shift_left(w.angle_guard))
        for norm, bits in X.NORMS.items():
            with m.Case(norm):
                with m.If(v[top - bits:] == 0):     # both fit shifted: the top bits + 1 are zero
                    m.d.sync += [x.eq(x.shift_left(bits)), y.eq(y.shift_left(bits))]
        with m.Case(X.K_COARSE, X.K_QROT, X.K_VEC, X.K_ROT):
            with m.If(go):
                m.d.sync += [x.eq(x_next), y.eq(y_next), z.eq(z_next)]
        with m.Default():       # the other operations hold the vector (a case for every value: lint-clean)
            m.d.sync += [x.eq(x), y.eq(y), z.eq(z)]
    with m.If(run & (op == X.K_COARSE)):
        m.d.sync += regs["zero"].eq((x == 0) & (y == 0))

def b_factor_bits(w) -> int:
    """Bits of the B factor: a limb (two with the wide product step, ``w.b_limbs``) or a check
    word."""
    return max(X.LIMB * w.b_limbs + 1, CHECK_BITS)


def _piece(reg, lsb: int, n: int, top):
    """Bits [lsb, lsb + n) of ``reg`` unsigned, or with the next bit as the sign if ``top``; a
    piece that reaches the register's end is its signed top (the last limb is always the top)."""
    if lsb + n < len(reg):
        return Cat(reg[lsb:lsb + n], top & reg[lsb + n]).as_signed()
    rest = reg[lsb:]
    return Cat(rest, rest[-1].replicate(n + 1 - len(rest))).as_signed()


def multiplier(m, ins, next_shift, bus, regs, run, w, shifts, dsp: str = Dsp.GENERIC):
    """The operand registers, the limb pick and the one limb multiplier (16 x 16 bits, or 16 x
    31 with the wide product step); ``dsp`` ecp5: the limb registers are the input registers of
    ``MULT18X18D`` primitives (:func:`_dsp_product`), the same clocks and bits."""
    def limb(reg, index, top, check, size=1):
        n = X.LIMB * size
        options = [_piece(reg, n * i, n, top) for i in range(-(-w.limbs // size))]
        return Mux(check, reg[w.check_lsb:w.check_lsb + CHECK_BITS].as_signed(),
                   select(options, index).as_signed())

    def picked():
        return limb(regs["ma"], ins.pa, ins.psa, ins.pwa), limb(regs["mb"], ins.pb, ins.psb, ins.pwb, w.b_limbs)

    product = Signal(signed(_FACTOR_BITS + b_factor_bits(w)), name="limb_product")   # the one multiplier
    if dsp == Dsp.ECP5:
        m.d.comb += product.eq(_dsp_product(m, *picked(), run & ins.pick))
    else:
        m.d.comb += product.eq(regs["la"] * regs["lb"])
    with m.If(run):
        # The product register holds the limb product already shifted to its weight, by
        # the shift of the instruction that adds it (the next one to execute).
        m.d.sync += regs["prod"].eq(onehot_select([product.shift_left(s) for s in shifts], next_shift)
                                    if len(shifts) > 1 else product.shift_left(shifts[0]))
        if dsp != Dsp.ECP5:
            with m.If(ins.pick):
                m.d.sync += [regs[name].eq(value) for name, value in zip(("la", "lb"), picked())]
        with m.Switch(ins.mld):
            with m.Case(X.MulLoad.A):
                m.d.sync += regs["ma"].eq(bus)
            with m.Case(X.MulLoad.B):
                m.d.sync += regs["mb"].eq(bus)
            with m.Default():
                m.d.sync += [regs["ma"].eq(regs["ma"]), regs["mb"].eq(regs["mb"])]


def _signed18(value):
    """``value`` (signed, at most 18 bits) sign-extended to a ``MULT18X18D`` operand."""
    return Cat(value, value[-1].replicate(MULT_BITS - len(value)))


def _dsp_product(m, a, b, enable):
    """``a * b`` (signed, ``a`` at most 18 bits, ``b`` at most 35) from ``MULT18X18D``s whose
    input registers take ``a`` and ``b`` where ``enable`` (the limb registers' load): one DSP,
    or two for a wide ``b`` (its low 17 bits unsigned, the rest signed; their products summed
    in the fabric). The product follows the operands by a clock, as the limb registers'."""
    if len(a) > MULT_BITS or len(b) > 2 * MULT_BITS - 1:
        raise ValueError(f"a {len(a)} x {len(b)}-bit product does not fit two MULT18X18D")
    if len(b) <= MULT_BITS:
        return mult18x18d(m, "limb", _signed18(a), _signed18(b), enable=enable, output_register=False)
    low_bits = MULT_BITS - 1
    low = mult18x18d(m, "limb_low", _signed18(a), Cat(b[:low_bits], Const(0, 1)), enable=enable,
                     output_register=False)
    high = mult18x18d(m, "limb_high", _signed18(a), _signed18(b[low_bits:].as_signed()), enable=enable,
                      output_register=False)
    return high.shift_left(low_bits) + low


def _digit(m, rad, root, rem, w, name):
    """One digit step of the square root from (rad, root, rem): the next values, each cut to
    its register's width."""
    shifted = Cat(rad[w.radicand - 2:], rem)
    trial = Cat(Const(1, 2), root)
    diff = Signal(signed(len(shifted) + 1), name=f"{name}_diff")
    m.d.comb += diff.eq(shifted - trial)
    nxt = [Signal.like(reg, name=f"{name}_{reg.name}") for reg in (rad, root, rem)]
    m.d.comb += [nxt[0].eq(rad.shift_left(2)), nxt[1].eq(Cat(~diff[-1], root)),
                 nxt[2].eq(Mux(diff[-1], shifted, diff))]
    return nxt


def sqrt(m, ins, acc, regs, run, w):
    """The digit-serial square root: one digit a clock, or two (``Q_STEP2``: two digit steps
    chained, two subtractions in one clock, off the engine's slowest paths)."""
    rad, root, rem = regs["rad"], regs["root"], regs["rem"]
    one = _digit(m, rad, root, rem, w, "sqrt")
    two = _digit(m, *one, w, "sqrt2")
    with m.If(run), m.Switch(ins.sq):
        with m.Case(X.Q_LOAD):
            m.d.sync += [rad.eq(acc[:w.radicand]), root.eq(0), rem.eq(0)]
        with m.Case(X.Q_STEP):
            m.d.sync += [reg.eq(value) for reg, value in zip((rad, root, rem), one)]
        with m.Case(X.Q_STEP2):
            m.d.sync += [reg.eq(value) for reg, value in zip((rad, root, rem), two)]
        with m.Default():
            m.d.sync += [reg.eq(reg) for reg in (rad, root, rem)]
