"""The IK as a program of the sequenced engine: :func:`ik_program` (bit-exact to ``model.ik_solve``).

The program follows ``firmware/model.py`` step by step (the same order of rounding points,
saturations and status bits), in the units of :mod:`.seq_isa`. Work on independent units runs
side by side (:meth:`Asm.par`): while a CORDIC runs its micro-rotations, the multiplier, the
accumulator and the square root work on the next step's products, so a q32w pose takes about
700 clocks on one CORDIC unit, one 17 x 17 multiplier and one digit-serial square root.
"""

from __future__ import annotations

from ik5r.core import status as S
from ik5r.core.fxconfig import CHECK_BITS, Constants

from .cordic import atan2_widths, rotate_z_bound
from .seq_isa import (
    A_ADD,
    A_CMPGT,
    A_CMPLT,
    A_LD,
    A_MACC,
    A_MLD,
    A_NEG,
    A_NOP,
    A_SATI,
    A_SATW,
    A_SHR1,
    A_SHR4,
    A_SHR16,
    A_SUB,
    B_ACC,
    B_CX,
    B_CY,
    B_CZ,
    B_IN,
    B_MEM,
    B_REM,
    B_ROOT,
    C_BACK,
    C_DOWN,
    C_F,
    C_ROLL,
    C_ZERO,
    INPUT_WORDS,
    IO_FLAGS,
    IO_IN,
    IO_OUT,
    IO_STATUS,
    K_COARSE,
    K_LDX,
    K_LDXG,
    K_LDY,
    K_LDYG,
    K_LDZA,
    K_NORM1,
    K_NORM8,
    K_QROT,
    K_ROT,
    K_VEC,
    LIMB,
    Q_LOAD,
    Q_STEP,
    READ_AHEAD,
    Program,
    Widths,
)

__all__ = ["ik_program", "Asm"]


class Const:
    """A constant operand (a word of the data memory's constant pool)."""

    def __init__(self, value: int):
        self.value = int(value)


class Check:
    """The check word of a variable (its top CHECK_BITS bits: ``model.check_word`` of the internal
    format) as a multiplier operand: the variable is loaded, the pick takes the check word."""

    def __init__(self, name: str):
        self.name = name


class Bus:
    """A B-bus source other than the memory."""

    def __init__(self, sel: int):
        self.sel = sel


CX, CY, CZ, ROOT, REM, ACC = (Bus(B_CX), Bus(B_CY), Bus(B_CZ), Bus(B_ROOT), Bus(B_REM),
                              Bus(B_ACC))
F, NOT_F = (C_F, 0), (C_F, 1)


def limbs_of(bits: int) -> int:
    """Limbs of a signed operand of ``bits`` bits (15-bit limbs, a 16-bit signed top limb)."""
    return 1 if bits <= 16 else 1 + -(-(bits - 16) // LIMB)


def operand(src) -> dict:
    if isinstance(src, Bus):
        return {"bsel": src.sel}
    if isinstance(src, Const):
        return {"rd": ("c", src.value)}
    if isinstance(src, Check):
        return {"rd": ("v", src.name)}
    return {"rd": ("v", src)}


def _pick(src, index: int, limbs: int, side: str = "a") -> dict:
    """Pick fields of one operand: limb ``index`` (signed if the top one), or its check word."""
    if isinstance(src, Check):
        return {f"pw{side}": 1}
    return {f"p{side}": index, f"ps{side}": int(index == limbs - 1)}


def I(*conds, **fields) -> dict:
    """One instruction; ``conds``: up to two (source, invert) pairs."""
    for (src, inv), (a, b) in zip(conds, (("ca", "cai"), ("cb", "cbi"))):
        fields[a], fields[b] = src, inv
    return fields


def alu(op, src=None, *conds, **fields) -> dict:
    return I(*conds, alu=op, **(operand(src) if src is not None else {}), **fields)


def st(name: str) -> dict:
    return {"wr": 1, "wa": ("v", name)}


def shr(n: int) -> list:
    ops = []
    for size, op in ((16, A_SHR16), (4, A_SHR4), (1, A_SHR1)):
        while n >= size:
            ops.append(alu(op))
            n -= size
    return ops


class Asm:
    """Builds the instruction list; resolves constants and variables to memory addresses."""

    def __init__(self, k: Constants):
        self.k, self.ki = k, k.internal
        self.nearest = k.cfg.round_nearest
        self.shifts: list[int] = []
        self.operand_bits = 16
        self.product_bits = 0

    # -- arithmetic helpers (instruction lists) --
    def round_shift(self, n: int) -> list:
        """acc = rshift_round(acc, n)."""
        if n <= 0:
            return []
        return ([alu(A_ADD, Const(1 << (n - 1)))] if self.nearest else []) + shr(n)

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
            la, lb = (1 if isinstance(x, Check) else limbs_of(bits) for x, bits in ((a, a_bits), (b, b_bits)))
            if isinstance(a, Check) or isinstance(b, Check):
                self.operand_bits = max(self.operand_bits, CHECK_BITS)
            put(t, mld=1, **operand(a))
            key = (b.value if isinstance(b, Const) else b.name if isinstance(b, Check) else b, b_bits)
            if key != last_b:
                put(t + 1, mld=2, **operand(b))
                t += 1
            last_b = key
            t += 1
            if negative and not first_macc:
                raise ValueError("only the first term of a sum may be negative")
            for i in range(la):
                for j in range(lb):
                    put(t, pick=1, **_pick(a, i, la), **_pick(b, j, lb, "b"))
                    put(t + 2, alu=A_MLD if first_macc else A_MACC,
                        sh=self.shift_index(LIMB * (i + j) + extra))
                    first_macc = False
                    t += 1
            if negative:
                put(t + 2, alu=A_NEG)
            t -= 1      # the next term's MA load may share the last pick's clock
        return slots

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
        return ([I(cop=K_COARSE, ci=self.ki.cfg.iterations)] + [I(cop=K_NORM8)] * ((w - 1) // 8)
                + [I(cop=K_NORM1)] * 7
                + [I(cop=K_VEC, ci=i) for i in range(self.ki.cfg.iterations)])

    def atan2_angle(self, zero_status=0) -> list:
        """acc = the angle of the vectoring just run (0 for the zero vector)."""
        return ([alu(A_LD, CZ)] + self.round_shift(self.ki.cfg.angle_guard_bits)
                + [alu(A_LD, Const(0), (C_ZERO, 0), stat=zero_status)])

    def atan2(self, y, x, dest, zero_status=0) -> list:
        return ([I(cop=K_LDXG, **operand(x)), I(cop=K_LDYG, **operand(y))] + self.atan2_body()
                + self.atan2_angle(zero_status) + [st(dest)])

    def rotate(self, x, y, angle: str, dest_x: str, dest_y: str, beside=()) -> list:
        """(dest_x, dest_y) = cordic_rotate(x, y, angle) (saturated, flagged); ``beside``: work on
        the other units during the micro-rotations."""
        ki = self.ki
        c = ki.cfg
        code = [I(cop=K_LDZA, **operand(angle)), I(cop=K_LDX, **operand(x)), I(cop=K_LDY, **operand(y)),
                alu(A_LD, CZ), alu(A_CMPGT, Const(ki.half_pi_z)), I(cop=K_QROT, ci=c.iterations),
                alu(A_LD, CZ), alu(A_CMPLT, Const(-ki.half_pi_z)), I(cop=K_QROT, ci=c.iterations)]
        gain = Const(ki.inv_gain)
        for src, load in ((CX, K_LDX), (CY, K_LDY)):
            code += self.products([(src, c.width + 1, gain, ki.inv_gain.bit_length() + 1, False, 0)])
            code += self.round_shift(ki.inv_gain_frac - c.guard_bits)
            if load == K_LDX:
                code += [st("rot_gx")]
        code += [I(cop=K_LDY, bsel=B_ACC), I(cop=K_LDX, **operand("rot_gx"))]
        code += self.par([I(cop=K_ROT, ci=i) for i in range(c.iterations)], list(beside))
        for src, dest in ((CX, dest_x), (CY, dest_y)):
            code += [alu(A_LD, src)] + self.round_shift(c.guard_bits)
            code += [alu(A_SATI, stat=S.SATURATED), st(dest)]
        return code

    # -- assembly --
    @staticmethod
    def par(a: list, b: list) -> list:
        """Two instruction streams on disjoint units, clock by clock."""
        out = []
        for n in range(max(len(a), len(b))):
            x = a[n] if n < len(a) else {}
            y = b[n] if n < len(b) else {}
            if set(x) & set(y):
                raise ValueError(f"par: {x} and {y} share fields")
            out.append({**x, **y})
        return out

    def finish(self, code: list, widths: Widths) -> Program:
        code = _fold(code)
        code = _hazards(code)
        consts, names = {}, {}
        for ins in code:
            for key in ("rd", "wa"):
                ref = ins.get(key)
                if isinstance(ref, tuple) and ref[0] == "c":
                    consts.setdefault(ref[1], len(consts))
        base = len(consts)
        for ins in code:
            for key in ("rd", "wa"):
                ref = ins.get(key)
                if isinstance(ref, tuple) and ref[0] == "v":
                    names.setdefault(ref[1], base + len(names))
        for ins in code:
            for key in ("rd", "wa"):
                ref = ins.get(key)
                if isinstance(ref, tuple):
                    ins[key] = consts[ref[1]] if ref[0] == "c" else names[ref[1]]
        depth = 1 << max(1, (base + len(names) - 1).bit_length())
        mem_init = [0] * depth
        for value, addr in consts.items():
            mem_init[addr] = value
        const_bits = max(abs(v).bit_length() + 1 for v in consts)
        widths.mem = max(widths.mem, const_bits)
        widths.acc = max(widths.acc, widths.mem + 2)
        atan = list(self.ki.atan_table) + [self.ki.half_pi_z]
        return Program(code=code, mem_init=mem_init, atan=atan, shifts=list(self.shifts),
                       widths=widths, names=names)


def _reads_mem(ins) -> bool:
    uses_b = (ins.get("alu", 0) in (A_LD, A_ADD, A_SUB, A_CMPGT, A_CMPLT) or ins.get("mld", 0)
              or ins.get("cop", 0) in (K_LDX, K_LDY, K_LDXG, K_LDYG, K_LDZA))
    return bool(uses_b) and ins.get("bsel", 0) == B_MEM


def _fold(code: list) -> list:
    """A store-only instruction is merged into the next one (a store writes the accumulator as it
    was before its instruction, so the result is the same, one clock earlier)."""
    out = []
    pending = None
    for ins in code:
        if pending is not None and "wr" not in ins and not (
                _reads_mem(ins) and ins.get("rd") == pending["wa"]):
            ins = {**ins, **pending}
            pending = None
        elif pending is not None:
            out.append(pending)
            pending = None
        if set(ins) <= {"wr", "wa"} and ins:
            pending = ins
            continue
        out.append(ins)
    if pending is not None:
        out.append(pending)
    return out


def _hazards(code: list) -> list:
    """No-ops between a store and a read of the same word less than READ_AHEAD + 1 clocks later
    (the read happens READ_AHEAD clocks ahead of its instruction)."""
    out = []
    for ins in code:
        while _reads_mem(ins) and any(prev.get("wr") and prev.get("wa") == ins.get("rd")
                                      for prev in out[-READ_AHEAD:]):
            if any(o.get("pick") for o in out[-2:]):
                raise ValueError(f"store/read hazard inside a product at {ins}")
            out.append({})
        out.append(ins)
    return out


def _widths(k: Constants) -> Widths:
    ki = k.internal
    c = ki.cfg
    z = max(atan2_widths(ki)["cz"].width, rotate_z_bound(ki).bit_length() + 1)
    return Widths(word=k.cfg.width, guard=k.cfg.internal_guard_bits, internal=c.width,
                  acc=2 * c.width + 6, mem=c.width + 4, limbs=1, xy=c.width + c.guard_bits + 3,
                  z=z, radicand=2 * c.width, cordic_guard=c.guard_bits,
                  angle_guard=c.angle_guard_bits, check_lsb=ki.check_shift)


def ik_program(k: Constants) -> Program:
    """``model.ik_solve`` as a program of the sequenced engine (see the module docstring)."""
    a = Asm(k)
    ki = k.internal
    if ki.check_shift != k.check_shift + k.cfg.internal_guard_bits:
        raise ValueError("the frame's check words (of the word format) must be the top bits of the "
                         f"internal words: check_shift {k.check_shift} + guard != {ki.check_shift}")
    code = _joint1_to_roll(a) + _elbow_to_joints(a)
    widths = _widths(k)
    widths.limbs = limbs_of(a.operand_bits)
    widths.acc = max(widths.acc, a.product_bits + 3)
    return a.finish(code, widths)


def _joint1_to_roll(a: Asm) -> list:
    """The inputs, joint 1, the tool pitch, the wrist centre and q5 (the orientation checks and
    the elbow's products beside the CORDICs)."""
    ki, c = a.ki, a.ki.cfg
    wi, fu = c.width, c.frac_unit
    code = []
    for index, name in enumerate(INPUT_WORDS):
        code += [I(io=IO_IN, iw=index, bsel=B_IN, alu=A_LD), st(name)]
    code += [I(io=IO_FLAGS, iw=len(INPUT_WORDS))]

    # Joint 1: rho = sat(isqrt(px^2 + py^2)) beside theta1 = atan2(py, px), or atan2(ay, ax) when
    # rho = 0 (F: the radicand is not zero).
    code += a.products([("px", wi, "px", wi, False, 0), ("py", wi, "py", wi, False, 0)])
    code += [alu(A_CMPGT, Const(0), sq=Q_LOAD)]
    theta = [I(cop=K_LDXG, **operand("px")), I(NOT_F, cop=K_LDXG, **operand("ax")),
             I(cop=K_LDYG, **operand("py")), I(NOT_F, cop=K_LDYG, **operand("ay"))]
    theta += a.atan2_body() + a.atan2_angle(S.SINGULAR_BASE) + [st("theta1")]
    # The orientation checks' products fill the clocks the CORDIC runs alone (they only set status
    # bits): the frame's beside this vectoring and the rotations, the plane's once c1, s1 are known.
    checks = frame_checks(a)
    beside = [{}] * 4 + _fill(len(a.atan2_body()), checks)
    code += a.par(theta, a.par([I(sq=Q_STEP)] * wi, beside))
    code += sqrt_round(a) + [alu(A_SATI, stat=S.SATURATED)]
    code += [alu(A_NEG, None, (C_BACK, 0)), alu(A_SUB, Const(ki.a1_l)), st("xa")]
    code += [alu(A_LD, "theta1")] + a.opposite((C_BACK, 0)) + [st("q1")]
    code += a.rotate(Const(ki.one_u), Const(0), "q1", "c1", "s1", _fill(c.iterations, checks))

    # Tool pitch phi beside the roll's s5, c5.
    code += a.products([("ax", wi, "c1", wi, False, 0), ("ay", wi, "s1", wi, False, 0)])
    code += a.round_shift(fu) + [alu(A_SATI, stat=S.SATURATED), st("arad")]
    roll = []
    for dest, (u, v) in (("s5", ("nx", "ny")), ("c5", ("ox", "oy"))):
        roll += a.products([(v, wi, "c1", wi, True, 0), (u, wi, "s1", wi, False, 0)])
        roll += a.round_shift(fu) + [alu(A_SATI, None, (C_ROLL, 0), stat=S.SATURATED), st(dest)]
    code += [I(cop=K_LDXG, **operand("az")), I(cop=K_LDYG, **operand("arad"))]
    code += a.par(a.atan2_body(), roll)
    code += a.atan2_angle(S.INVALID) + a.opposite() + [st("phi")]

    # Wrist centre: the rotated offset, then the roll's atan2 beside the elbow's products.
    checks.insert(0, plane_check(a))
    code += a.rotate(Const(ki.a4_l), Const(ki.d5_l), "phi", "offx", "offy", _fill(c.iterations, checks))
    code += [ins for check in checks for ins in check]
    code += [I(cop=K_LDXG, **operand("c5")), I(cop=K_LDYG, **operand("s5"))]
    code += a.par(a.atan2_body(), elbow(a))
    code += a.atan2_angle() + [alu(A_NOP, None, (C_ZERO, 0), (C_ROLL, 0), stat=S.INVALID)]
    code += [alu(A_LD, "q5d", (C_ROLL, 1)), st("q5")]
    return code


def _elbow_to_joints(a: Asm) -> list:
    """gamma, sin q3, q3, beta, q2, q4 and the five joint words out with the status."""
    ki, fu, radicand = a.ki, a.ki.cfg.frac_unit, 2 * a.ki.cfg.width
    # gamma = atan2(yw, xw) beside sin q3 = isqrt((1 - c3)(1 + c3)).
    sine = a.products([("om", fu + 3, "op", fu + 3, False, radicand - (2 * fu + 4))])
    sine += [I(sq=Q_LOAD)] + [I(sq=Q_STEP)] * (fu + 2)
    code = [I(cop=K_LDXG, **operand("xw")), I(cop=K_LDYG, **operand("yw"))]
    code += a.par(a.atan2_body(), sine)
    code += a.atan2_angle() + [st("gamma")] + sqrt_round(a) + [st("s3")]

    # q3 = acos(c3) = atan2(sin q3, c3) beside the products of beta.
    m = ki.a3_from_u
    beta = [alu(A_LD, "s3"), alu(A_CMPLT, Const(ki.singular_s3_u + 1), stat=S.SINGULAR_ELBOW)]
    beta += a.mul_const(m, fu + 3) + [st("by"), alu(A_LD, "c3")]
    beta += a.mul_const(m, fu + 3) + [alu(A_ADD, Const(ki.a2_l)), st("bx")]
    code += [I(cop=K_LDXG, **operand("c3")), I(cop=K_LDYG, **operand("s3"))]
    code += a.par(a.atan2_body(), beta)
    code += a.atan2_angle() + [alu(A_NEG, None, (C_DOWN, 0)), st("q3")]

    # beta = atan2(by, bx) beside joints 1, 3, 5; then q2, q4.
    joints = []
    for index in (0, 2, 4):
        joints += joint(a, f"q{index + 1}", index)
    code += [I(cop=K_LDXG, **operand("bx")), I(cop=K_LDYG, **operand("by"))]
    code += a.par(a.atan2_body(), joints)
    code += a.atan2_angle() + [st("beta"), alu(A_LD, "gamma"), alu(A_ADD, "beta", (C_DOWN, 0)),
                               alu(A_SUB, "beta", (C_DOWN, 1))] + a.wrap() + [st("q2")]
    code += joint(a, "q2", 1)
    code += [alu(A_LD, "phi"), alu(A_SUB, "q2")] + a.wrap() + [alu(A_SUB, "q3")] + a.wrap()
    code += [st("q4")] + joint(a, "q4", 3)
    code += [alu(A_LD, "j0")]
    for index in range(1, 5):
        code += [alu(A_LD, f"j{index}", io=IO_OUT, iw=index - 1)]
    code += [I(io=IO_OUT, iw=4), I(io=IO_STATUS)]
    return code


def sqrt_round(a: Asm) -> list:
    """acc = the square root just run, rounded (``rem > root``: root + 1)."""
    if not a.nearest:
        return [alu(A_LD, ROOT)]
    return [alu(A_LD, REM), alu(A_CMPGT, ROOT), alu(A_LD, ROOT), alu(A_ADD, Const(1), F)]


def joint(a: Asm, name: str, index: int) -> list:
    """j<index> = sat(rshift_round(wrap(q - offset), guard)) from variable ``name``."""
    offset = a.ki.offset_a[index]
    code = [alu(A_LD, name)] + ([alu(A_SUB, Const(offset))] if offset else []) + a.wrap()
    code += a.round_shift(a.k.cfg.internal_guard_bits)
    return code + [alu(A_SATW, stat=S.SATURATED), st(f"j{index}")]


def elbow(a: Asm) -> list:
    """xw, yw, the law of cosines clipped to the annulus, 1 -+ c3 and c3 (model.ik_solve)."""
    ki = a.ki
    c = ki.cfg
    wi = c.width
    code = [alu(A_LD, "xa"), alu(A_SUB, "offx"), alu(A_SATI, stat=S.SATURATED), st("xw"),
            alu(A_LD, Const(ki.d1_l)), alu(A_SUB, "pz"), alu(A_SUB, "offy"),
            alu(A_SATI, stat=S.SATURATED), st("yw"), alu(A_LD, Const(-ki.links_sq_l2))]
    code += a.products([("xw", wi, "xw", wi, False, 0), ("yw", wi, "yw", wi, False, 0)], first=False)
    limit, reach = ki.twice_a2a3_l2, int(ki.reach_limit_l2)
    code += [alu(A_CMPGT, Const(reach), stat=S.UNREACHABLE), alu(A_CMPLT, Const(-reach), stat=S.UNREACHABLE),
             alu(A_CMPGT, Const(limit)), alu(A_LD, Const(limit), F),
             alu(A_CMPLT, Const(-limit)), alu(A_LD, Const(-limit), F), st("num")]
    one, two = ki.one_u, 2 * ki.one_u
    bits = limit.bit_length() + 3
    if a.k.cfg.internal_guard_bits == 0:
        code += a.mul_const(ki.c3_from_l2, bits)
        code += [alu(A_CMPGT, Const(one)), alu(A_LD, Const(one), F),
                 alu(A_CMPLT, Const(-one)), alu(A_LD, Const(-one), F), st("c3"),
                 alu(A_LD, Const(one)), alu(A_SUB, "c3"), st("om"),
                 alu(A_LD, Const(one)), alu(A_ADD, "c3"), st("op")]
        return code
    m = ki.c3_complement_from_l2
    for dest, op in (("om", A_SUB), ("op", A_ADD)):
        code += [alu(A_LD, Const(limit)), alu(op, "num")] + a.mul_const(m, bits)
        code += [alu(A_CMPGT, Const(two)), alu(A_LD, Const(two), F), st(dest)]
    return code + [alu(A_LD, Const(one)), alu(A_SUB, "om"), st("c3")]


def _fill(window: int, streams: list) -> list:
    """The streams taken off the front of ``streams`` while they fit ``window`` clocks, in a row."""
    out = []
    while streams and len(out) + len(streams[0]) <= window:
        out += streams.pop(0)
    return out


def beyond(centre: int, k: Constants, *conds) -> list:
    """BAD_ORIENTATION if acc is beyond ``centre`` by more than the tolerance (``model.beyond``)."""
    tol = k.check_tol_c2
    return [alu(A_CMPGT, Const(centre + tol), *conds, stat=S.BAD_ORIENTATION),
            alu(A_CMPLT, Const(centre - tol), *conds, stat=S.BAD_ORIENTATION)]


def frame_checks(a: Asm) -> list:
    """``model.frame_is_bad`` (with roll only), one instruction list a check: n.n, o.o, n.o and
    the components of n x o - a, each a sum of check-word products against its centre."""
    k, wi = a.k, a.ki.cfg.width
    n, o = ([Check(f"{v}{axis}") for axis in "xyz"] for v in "no")

    def dot(u, v):
        return [(x, wi, y, wi, False, 0) for x, y in zip(u, v)]

    checks = [(dot(n, n), k.check_one_c2), (dot(o, o), k.check_one_c2), (dot(n, o), 0)]
    for i, axis in enumerate("xyz"):
        j, m = (i + 1) % 3, (i + 2) % 3
        # (n x o - a)_i = -n_m o_j (the one negative term first) + n_j o_m - a_i << check_frac.
        checks.append(([(n[m], wi, o[j], wi, True, 0), (n[j], wi, o[m], wi, False, 0),
                        (Check(f"a{axis}"), wi, Const(-1), 2, False, k.check_frac)], 0))
    return [a.products(terms) + beyond(centre, k, (C_ROLL, 0)) for terms, centre in checks]


def plane_check(a: Asm) -> list:
    """``model.off_plane``: the approach's component normal to the arm's plane, ay c1 - ax s1."""
    wi = a.ki.cfg.width
    terms = [(Check("ax"), wi, Check("s1"), wi, True, 0), (Check("ay"), wi, Check("c1"), wi, False, 0)]
    return a.products(terms) + beyond(0, a.ki)
