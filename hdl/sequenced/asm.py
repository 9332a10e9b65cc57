"""The assembler of the sequenced engine's programs: operands, instruction helpers and the unit
recipes the lowering (:mod:`.seq_lower`) builds blocks from (rounding shifts, angle wraps, limb
products, constant multiplies, the CORDIC's vectoring and rotation, the square root's rounding),
and :meth:`Asm.finish`, which resolves constants and variables to data-memory addresses.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, replace

from ik5r.core import fixedpoint
from ik5r.core.fxconfig import CHECK_BITS, Constants

from ..blocks.cordic import atan2_widths, rotate_z_bound
from .isa import (A_ADD, A_CMPGT, A_CMPLT, A_LD, A_MACC, A_MLD, A_NEG, A_SATI, A_SATW, A_SUB,
                  B_ACC, B_CX, B_CY, B_CZ, B_MEM, B_REM, B_ROOT, C_F, C_ZERO, K_COARSE, K_LDX,
                  K_LDXG, K_LDY, K_LDYG, K_LDZA, K_QROT, K_ROT, K_VEC, LIMB, NORMS, READ_AHEAD,
                  SHIFTS, BusSource, nonzero, Const, Ins, MulLoad, Program, Var, Widths)
from .shifts import shift_ops

__all__ = ["Asm", "Const", "Check", "Bus"]


@dataclass(frozen=True)
class Check:
    """The check word of a variable (its top CHECK_BITS bits: ``model.check_word`` of the internal
    format) as a multiplier operand: the variable is loaded, the pick takes the check word."""
    name: str


@dataclass(frozen=True)
class Bus:
    """A B-bus source other than the memory."""
    sel: BusSource


CX, CY, CZ, ROOT, REM, ACC = (Bus(B_CX), Bus(B_CY), Bus(B_CZ), Bus(B_ROOT), Bus(B_REM),
                              Bus(B_ACC))
F, NOT_F = (C_F, 0), (C_F, 1)


def limbs_of(bits: int) -> int:
    """Limbs of a signed operand of ``bits`` bits (15-bit limbs, a 16-bit signed top limb)."""
    return 1 if bits <= 16 else 1 + -(-(bits - 16) // LIMB)


def operand(src) -> dict:
    """The fields that put ``src`` on the B bus: a :class:`Bus` source, a :class:`Const`, a
    :class:`Check` (its variable's word) or a variable's name."""
    if isinstance(src, Bus):
        return {"bsel": src.sel}
    if isinstance(src, Const):
        return {"rd": src}
    if isinstance(src, Check):
        return {"rd": Var(src.name)}
    return {"rd": Var(src)}


def _pick(src, index: int, limbs: int, side: str = "a") -> dict:
    """Pick fields of one operand: limb ``index`` (signed if the top one), or its check word."""
    if isinstance(src, Check):
        return {f"pw{side}": 1}
    return {f"p{side}": index, f"ps{side}": int(index == limbs - 1)}


def I(*conds, **fields) -> Ins:
    """One instruction; ``conds``: up to two (source, invert) pairs."""
    if len(conds) > 2:
        raise ValueError(f"an instruction has two condition slots, not {len(conds)}: {conds}")
    for (src, inv), (a, b) in zip(conds, (("ca", "cai"), ("cb", "cbi"))):
        fields[a], fields[b] = src, inv
    return Ins(**fields)


def alu(op, src=None, *conds, **fields) -> Ins:
    return I(*conds, alu=op, **(operand(src) if src is not None else {}), **fields)


def st(name: str) -> Ins:
    return Ins(wr=1, wa=Var(name))


def normalising_shifts(most: int) -> list[int]:
    """Shifts (each of :data:`~.isa.NORMS`) whose conditional sequence, each taken if x and y
    both still fit, shifts by exactly ``min(headroom, most)``: each at most one more than the
    sum of those after it, so a shift skipped is made up by the rest."""
    sizes, rest = [], most
    while rest:
        size = max(s for s in NORMS.values() if 2 * s <= rest + 1)
        sizes.append(size)
        rest -= size
    return sizes


class Asm:
    """Builds the instruction list; resolves constants and variables to memory addresses."""

    def __init__(self, k: Constants, *, wide_product: bool = False, acc_shifts: tuple = (1, 4, 16)):
        self.k, self.ki = k, k.internal
        #: The accumulator's shifts right (bits of each op of SHIFTS), and the amounts asked of
        #: them (bits -> times: :func:`.shifts.acc_shifts_for` picks a program's three).
        self.acc_shifts = tuple(acc_shifts)
        self.shifted: Counter = Counter()
        #: Limbs of the B operand per pick (the wide product step multiplies 16 x 31 bits).
        self.b_size = 2 if wide_product else 1
        self.nearest = k.cfg.round_nearest
        self.shifts: list[int] = []
        self.operand_bits = 16
        self.product_bits = 0

    # -- arithmetic helpers (instruction lists) --
    def round_shift(self, n: int) -> list:
        """acc = rshift_round(acc, n)."""
        if n <= 0:
            return []
        return ([alu(A_ADD, Const(1 << (n - 1)))] if self.nearest else []) + self.shr(n)

    def shr(self, n: int) -> list:
        """acc >>= n (arithmetic), in the fewest of the accumulator's shifts."""
        self.shifted[n] += 1
        sizes = shift_ops(n, self.acc_shifts)
        if sizes is None:
            raise ValueError(f"no sum of the accumulator's shifts {self.acc_shifts} is {n}")
        return [alu(SHIFTS[self.acc_shifts.index(size)]) for size in sizes]

    def clip(self, lo: int | None, hi: int | None) -> list:
        """acc = clip(acc, lo, hi) (None: no bound that side): one saturation (no status bit)
        where the bounds are a format's range, else a compare and a load per bound."""
        sat = self.saturating(lo, hi)
        if sat is not None:
            return [alu(sat)]
        code = [alu(A_CMPGT, Const(hi)), alu(A_LD, Const(hi), F)] if hi is not None else []
        return code + ([alu(A_CMPLT, Const(lo)), alu(A_LD, Const(lo), F)] if lo is not None else [])

    def saturating(self, lo: int | None, hi: int | None):
        """The saturation (``SATI``/``SATW``) that is ``clip(acc, lo, hi)``, if any: each bound
        given that of the internal or of the word format, the same for both."""
        for op, bits in ((A_SATI, self.ki.cfg.width), (A_SATW, self.k.cfg.width)):
            top = (1 << (bits - 1)) - 1
            if (lo, hi) != (None, None) and lo in (None, -top - 1) and hi in (None, top):
                return op
        return None

    def wrap(self) -> list:
        """acc = wrap_angle(acc)."""
        pi = self.ki.pi_a
        return [alu(A_CMPGT, Const(pi)), alu(A_SUB, Const(2 * pi), F),
                alu(A_CMPLT, Const(-pi)), alu(A_ADD, Const(2 * pi), F)]

    def opposite(self, *conds) -> list:
        """acc = opposite(acc) (when ``conds`` hold)."""
        pi = self.ki.pi_a
        return [alu(A_CMPGT, Const(0)), alu(A_SUB, Const(pi), F, *conds),
                alu(A_ADD, Const(pi), NOT_F, *conds)]

    def shift_index(self, amount: int) -> int:
        if amount not in self.shifts:
            self.shifts.append(amount)
        return self.shifts.index(amount)

    def products(self, terms, *, first=True) -> list:
        """acc (+)= sum of +-a*b; ``terms``: (a, a_bits, b, b_bits, negative, extra_shift).

        Per term: the operands are loaded (MB only when it changes), one limb pair is picked per
        clock, and its product is added two clocks later (the multiplier's two registers). A
        :class:`Check` operand is one limb, its check word."""
        slots: list[dict] = []

        def put(t, **fields):
            while len(slots) <= t:
                slots.append({})
            if set(fields) & set(slots[t]):
                raise ValueError(f"slot {t}: {fields} clashes with {slots[t]}")
            slots[t].update(fields)

        t, last_b, first_macc = 0, None, first
        for index, (a, a_bits, b, b_bits, negative, extra) in enumerate(terms):
            self.operand_bits = max(self.operand_bits, a_bits, b_bits)
            self.product_bits = max(self.product_bits, a_bits + b_bits + extra)
            if self._cheaper_swapped(a, a_bits, b, b_bits):
                a, a_bits, b, b_bits = b, b_bits, a, a_bits
            la, lb = (1 if isinstance(x, Check) else limbs_of(bits) for x, bits in ((a, a_bits), (b, b_bits)))
            lb = -(-lb // self.b_size)
            if isinstance(a, Check) or isinstance(b, Check):
                self.operand_bits = max(self.operand_bits, CHECK_BITS)
            put(t, mld=MulLoad.A, **operand(a))
            key = (b.value if isinstance(b, Const) else b.name if isinstance(b, Check) else b, b_bits)
            if key != last_b:
                put(t + 1, mld=MulLoad.B, **operand(b))
                t += 1
            last_b = key
            t += 1
            if negative and not first_macc:
                raise ValueError("only the first term of a sum may be negative")
            for i in range(la):
                for j in range(lb):
                    put(t, pick=1, **_pick(a, i, la), **_pick(b, j, lb, "b"))
                    put(t + 2, alu=A_MLD if first_macc else A_MACC,
                        sh=self.shift_index(LIMB * (i + self.b_size * j) + extra))
                    first_macc = False
                    t += 1
            if negative:
                put(t + 2, alu=A_NEG)
            t -= 1      # the next term's MA load may share the last pick's clock
        return [Ins(**fields) for fields in slots]

    def _cheaper_swapped(self, a, a_bits, b, b_bits) -> bool:
        """With the wide step, the operand of more limbs goes to MB (fewer picks)."""
        if self.b_size == 1:
            return False
        la, lb = (1 if isinstance(x, Check) else limbs_of(bits) for x, bits in ((a, a_bits), (b, b_bits)))
        return lb * -(-la // self.b_size) < la * -(-lb // self.b_size)

    def mul_const(self, m, bits: int) -> list:
        """acc = mul_const(acc, m) for |acc| < 2**(bits - 1)."""
        if m.mant < 0:
            raise ValueError("negative constant multiplier")
        code = self.round_shift(m.pre)
        op_bits = max(2, bits - m.pre + 1)
        code += self.products([(ACC, op_bits, Const(m.mant), m.mant.bit_length() + 1, False, 0)])
        return code + self.round_shift(m.post)

    # -- CORDIC --
    def atan2_body(self) -> list:
        w = self.ki.cfg.width
        # The normalisation of the vector: up to 8 ((w - 1) // 8) + 7 bits (the models' shifts).
        norm = {bits: op for op, bits in NORMS.items()}
        return ([I(cop=K_COARSE, ci=self.ki.cfg.iterations)]
                + [I(cop=norm[bits]) for bits in normalising_shifts(8 * ((w - 1) // 8) + 7)]
                + [I(cop=K_VEC, ci=i) for i in range(self.ki.cfg.iterations)])

    def atan2_angle(self, zero_status=0, zero_events=()) -> list:
        """acc = the angle of the vectoring just run (0 for the zero vector: rounded, still 0).
        The zero vector's load and ``zero_events`` (instructions under its latch) come first,
        so the CORDIC is free before the rounding."""
        return ([alu(A_LD, CZ), alu(A_LD, Const(0), (C_ZERO, 0), stat=zero_status), *zero_events]
                + self.round_shift(self.ki.cfg.angle_guard_bits))

    def rotate(self, x, y, angle, dest_x: str, dest_y: str, temp: str, stat: int, gates=()) -> list:
        """(dest_x, dest_y) = cordic_rotate(x, y, angle): the quadrant steps, the gain on the
        inputs, the micro-rotations, the outputs rounded and saturated (``stat`` where ``gates``).
        A constant vector is gained first (:meth:`gained_quadrants`): no products."""
        ki = self.ki
        c = ki.cfg
        gained = self.gained_quadrants(x, y)
        if gained:
            x, y = map(Const, gained["none"])
        up, down = ([] if not gained or gained[case] is None
                    else [I(F, cop=load, rd=Const(gained[case]))]
                    for case, load in (("up_x", K_LDX), ("down_y", K_LDY)))
        code = [I(cop=K_LDZA, **operand(angle)), I(cop=K_LDX, **operand(x)), I(cop=K_LDY, **operand(y)),
                alu(A_LD, CZ), alu(A_CMPGT, Const(ki.half_pi_z)), I(cop=K_QROT, ci=c.iterations), *up,
                alu(A_LD, CZ), alu(A_CMPLT, Const(-ki.half_pi_z)), I(cop=K_QROT, ci=c.iterations), *down]
        if not gained:
            gain = Const(ki.inv_gain)
            for src, load in ((CX, K_LDX), (CY, K_LDY)):
                code += self.products([(src, c.width + 1, gain, ki.inv_gain.bit_length() + 1, False, 0)])
                code += self.round_shift(ki.inv_gain_frac - c.guard_bits)
                if load == K_LDX:
                    code += [st(temp)]
            code += [I(cop=K_LDY, bsel=B_ACC), I(cop=K_LDX, **operand(temp))]
        code += [I(cop=K_ROT, ci=i) for i in range(c.iterations)]
        for src, dest in ((CX, dest_x), (CY, dest_y)):
            code += [alu(A_LD, src)] + self.round_shift(c.guard_bits)
            code += [alu(A_SATI, None, *gates, stat=stat), st(dest)]
        return code

    def gained_quadrants(self, x, y) -> dict | None:
        """For a constant vector (x, y), its coordinates times the rotation's gain 1/K as the
        models round them, to load before the quadrant step instead of multiplying after it:
        ``none`` the gained vector; the quarter turn up makes (-y, x) of it, right unless the
        rounding of y is a tie (not odd), so ``up_x`` is then gained(-y), loaded after the
        turn (else None); likewise ``down_y``, gained(-x), after the turn down to (y, -x).
        None for other operands."""
        if not (isinstance(x, Const) and isinstance(y, Const)):
            return None
        ki = self.ki
        shift, nearest = ki.inv_gain_frac - ki.cfg.guard_bits, ki.cfg.round_nearest

        def gain(v):
            return fixedpoint.rshift_round(v * ki.inv_gain, shift, nearest)

        def turned(v):
            return None if gain(-v) == -gain(v) else gain(-v)

        return {"none": (gain(x.value), gain(y.value)), "up_x": turned(y.value), "down_y": turned(x.value)}

    # -- assembly --
    def finish(self, code: list, widths: Widths, cyclic: bool = False) -> Program:
        """The program of a scheduled instruction list (no store/read hazard left: checked, across
        its end too if ``cyclic``: its poses run on into the next run, :mod:`.modulo`)."""
        runs = code + code if cyclic else code
        if len(hazards(runs)) != len(runs):
            raise ValueError("a scheduled program reads a word within READ_AHEAD clocks of its store")
        consts, names = {}, {}
        for ins in code:
            if isinstance(ins.rd, Const):
                consts.setdefault(ins.rd.value, len(consts))
        base = len(consts)
        for ins in code:
            for ref in (ins.rd, ins.wa):
                if isinstance(ref, Var):
                    names.setdefault(ref.name, base + len(names))

        def address(ref):
            if isinstance(ref, Const):
                return consts[ref.value]
            return names[ref.name] if isinstance(ref, Var) else ref

        code = [replace(ins, rd=address(ins.rd), wa=address(ins.wa)) for ins in code]
        depth = 1 << max(1, (base + len(names) - 1).bit_length())
        mem_init = [0] * depth
        for value, addr in consts.items():
            mem_init[addr] = value
        const_bits = max(abs(v).bit_length() + 1 for v in consts)
        widths.mem = max(widths.mem, const_bits)
        widths.acc = max(widths.acc, widths.mem + 2)
        atan = list(self.ki.atan_table) + [self.ki.half_pi_z]
        return Program(code=code, mem_init=mem_init, atan=atan, shifts=list(self.shifts),
                       widths=widths, names=names, cyclic=cyclic, acc_shifts=self.acc_shifts)


def reads_mem(ins: Ins) -> bool:
    uses_b = (ins.alu in (A_LD, A_ADD, A_SUB, A_CMPGT, A_CMPLT) or nonzero(ins.mld)
              or ins.cop in (K_LDX, K_LDY, K_LDXG, K_LDYG, K_LDZA))
    return bool(uses_b) and (ins.bsel or B_MEM) == B_MEM


def _store_only(ins: Ins) -> bool:
    return bool(ins.present()) and ins.present() <= {"wr", "wa"}


def fold(code: list[Ins]) -> list[Ins]:
    """A store-only instruction is merged into the next one (a store writes the accumulator as it
    was before its instruction, so the result is the same, one clock earlier)."""
    out = []
    pending = None
    for ins in code:
        if pending is not None and ins.wr is None and not (reads_mem(ins) and ins.rd == pending.wa):
            ins = ins.merge(pending)
            pending = None
        elif pending is not None:
            out.append(pending)
            pending = None
        if _store_only(ins):
            pending = ins
            continue
        out.append(ins)
    if pending is not None:
        out.append(pending)
    return out


def hazards(code: list[Ins]) -> list[Ins]:
    """No-ops between a store and a read of the same word less than READ_AHEAD + 1 clocks later
    (the read happens READ_AHEAD clocks ahead of its instruction)."""
    out = []
    for ins in code:
        while reads_mem(ins) and any(prev.wr and prev.wa == ins.rd for prev in out[-READ_AHEAD:]):
            if any(o.pick for o in out[-2:]):
                raise ValueError(f"store/read hazard inside a product at {ins}")
            out.append(Ins())
        out.append(ins)
    return out


def widths_of(k: Constants) -> Widths:
    ki = k.internal
    c = ki.cfg
    z = max(atan2_widths(ki)["cz"].width, rotate_z_bound(ki).bit_length() + 1)
    return Widths(word=k.cfg.width, guard=k.cfg.internal_guard_bits, internal=c.width,
                  acc=2 * c.width + 6, mem=c.width + 4, limbs=1, xy=c.width + c.guard_bits + 3,
                  z=z, radicand=2 * c.width, cordic_guard=c.guard_bits,
                  angle_guard=c.angle_guard_bits, check_lsb=ki.check_shift)


def sqrt_round(a: Asm) -> list:
    """acc = the square root just run, rounded (``rem > root``: root + 1)."""
    if not a.nearest:
        return [alu(A_LD, ROOT)]
    return [alu(A_LD, REM), alu(A_CMPGT, ROOT), alu(A_LD, ROOT), alu(A_ADD, Const(1), F)]


