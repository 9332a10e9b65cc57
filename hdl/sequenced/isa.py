"""The micro-instruction set of the sequenced IK engine (:mod:`.seq_core`) and its reference
interpreter.

An instruction is a dict of fields (absent = 0), one field group per unit, all acting in the same
clock: the data memory (one read ``rd``, one write ``wa`` of the accumulator as it was before the
instruction), the accumulator ALU (``alu``, condition ``ca/cai & cb/cbi``, status mask ``stat``),
the CORDIC micro-rotation unit (``cop``, step ``ci``), the multiplier (``mld`` operand loads,
``pick`` of one 16 x 16 limb product, or of a product of check words, the top
:data:`~ik5r.core.fxconfig.CHECK_BITS` bits of an internal word, ``pwa`` / ``pwb``; two clocks later
accumulated by ``MACC`` / ``MLD``), the
digit-serial square root (``sq``) and the word ports (``io``). The program is straight-line (no
branches: selections are conditional ALU and CORDIC operations), so a pose takes exactly the
program's length in clocks, plus any wait on the word ports.

:func:`run` executes a :class:`Program` clock by clock, exactly as the hardware does (the memory
read of an instruction happens two clocks before it, the multiplier's two pipeline registers),
so it checks a program against ``model.ik_solve`` in milliseconds, before any HDL simulation.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ik5r.core.fxconfig import CHECK_BITS

from ..graph.inputs import INPUT_WORDS, BranchFlag

# --- field values --------------------------------------------------------------------------------

#: B-bus sources (``bsel``): memory word, input word (<< guard), CORDIC x / y / z, root,
#: remainder, the accumulator itself.
B_MEM, B_IN, B_CX, B_CY, B_CZ, B_ROOT, B_REM, B_ACC = range(8)

#: ALU operations (``alu``).
(A_NOP, A_LD, A_ADD, A_SUB, A_NEG, A_CMPGT, A_CMPLT, A_SHR1, A_SHR4, A_SHR16, A_SATI, A_SATW,
 A_MLD, A_MACC, A_SETF) = range(15)

#: The B-bus sources an adding ALU operation (``ADDING``) may take: the adder has its own operand
#: select of these few registers, off the B bus (the input word's and the CORDIC's paths through
#: the B bus into the adder's carry chain were the engine's slowest). Other sources are loaded
#: (``LD``, the CORDIC and multiplier loads).
ADDING = (A_ADD, A_SUB, A_CMPGT, A_CMPLT)
ADDER_SOURCES = (B_MEM, B_ROOT, B_ACC)

#: Condition sources (``ca``, ``cb``; ``cai``, ``cbi`` invert): always, F, shoulder_back,
#: elbow_down, has_roll, CORDIC zero vector.
C_ONE, C_F, C_BACK, C_DOWN, C_ROLL, C_ZERO = range(6)
#: The condition source of each branch flag of the traced graph.
FLAG_SOURCE = {BranchFlag.ROLL: C_ROLL, BranchFlag.BACK: C_BACK, BranchFlag.DOWN: C_DOWN}

#: CORDIC operations (``cop``): loads from the B bus (x, y; ``G``: shifted up by the CORDIC guard
#: bits, x also clears z; z shifted up by the angle guard bits), the vectoring coarse rotation
#: (by -+90 degrees if x < 0; latches the zero-vector flag), the rotation quadrant step (by -+90
#: degrees if F), the conditional normalising shifts by 8 and by 1, and micro-rotation ``ci``
#: (vectoring or rotation).
(K_NOP, K_LDX, K_LDY, K_LDXG, K_LDYG, K_LDZA, K_COARSE, K_QROT, K_NORM8, K_NORM1, K_VEC,
 K_ROT) = range(12)

#: Square root (``sq``): load the radicand from the accumulator, one digit step, two digit steps.
Q_NOP, Q_LOAD, Q_STEP, Q_STEP2 = range(4)

#: Word ports (``io``): input word ``iw`` on the B bus, the flags word (ends the input), output
#: word ``iw`` (the accumulator, before this instruction), the status word (ends the output).
IO_NOP, IO_IN, IO_FLAGS, IO_OUT, IO_STATUS = range(5)

FIELDS = ("rd", "bsel", "wr", "wa", "alu", "ca", "cai", "cb", "cbi", "stat", "sh", "cop", "ci",
          "mld", "pick", "pa", "pb", "psa", "psb", "pwa", "pwb", "sq", "io", "iw")

#: Fields owned by each unit (two instructions can be merged when their units are disjoint).
UNIT_FIELDS = {
    "mem": ("rd", "bsel", "wr", "wa"),
    "alu": ("alu", "ca", "cai", "cb", "cbi", "stat", "sh"),
    "cordic": ("cop", "ci"),
    "mul": ("mld", "pick", "pa", "pb", "psa", "psb", "pwa", "pwb"),
    "sqrt": ("sq",),
    "io": ("io", "iw"),
}

#: Clocks between an instruction's memory read and its execution: a store is seen by
#: instructions at least READ_AHEAD + 1 after it.
READ_AHEAD = 2
LIMB = 15          # unsigned limb bits; the top limb of an operand is 16 bits, signed


@dataclass
class Widths:
    """Register widths of the engine (derived by the program builder from the constants)."""

    word: int          # W: input and output words
    guard: int         # internal guard bits G (input words are shifted up by G)
    internal: int      # W + G
    acc: int           # accumulator
    mem: int           # data memory word
    limbs: int         # multiplier operand limbs (operand register 15 (limbs - 1) + 16 bits)
    xy: int            # CORDIC x, y
    z: int             # CORDIC z
    radicand: int      # square root radicand register (even)
    cordic_guard: int
    angle_guard: int
    check_lsb: int = 0  # a check word: operand bits [check_lsb, check_lsb + CHECK_BITS), signed
    tag: int = 0
    b_limbs: int = 1   # limbs of MB per pick: 2 with the wide product step (a 16 x 31 product)

    @property
    def operand(self) -> int:
        return LIMB * (self.limbs - 1) + 16


@dataclass
class Program:
    """A straight-line program, its data memory image and table ROM, and the engine's widths."""

    code: list
    mem_init: list           # memory words (constants; variables 0)
    atan: list               # CORDIC step angles by ``ci`` (last entry: half pi)
    shifts: list             # MACC / MLD shift amounts by ``sh``
    widths: Widths
    names: dict = field(default_factory=dict)   # variable name -> address

    def field_bits(self) -> dict:
        """Bits of each instruction field (at least 1)."""
        return {name: max(1, max(ins.get(name, 0) for ins in self.code).bit_length())
                for name in FIELDS}


def limb(value: int, index: int, top: bool, size: int = 1) -> int:
    """Limb ``index`` of an operand cut in limbs of ``size`` 15-bit limbs: 15 ``size`` unsigned
    bits, or, for the top one, the signed rest (16 bits for ``size`` 1)."""
    if top:
        bits = (value >> (LIMB * size * index)) & ((1 << (LIMB * size + 1)) - 1)
        return bits - (1 << (LIMB * size + 1)) if bits >> (LIMB * size) else bits
    return (value >> (LIMB * size * index)) & ((1 << (LIMB * size)) - 1)


def check_word(value: int, lsb: int) -> int:
    """The check word of an operand: its bits from ``lsb`` on (floor), CHECK_BITS bits, signed."""
    word = value >> lsb
    if not fits(word, CHECK_BITS):
        raise OverflowError(f"check word overflow {word} of {value}")
    return word


def wrap_signed(value: int, bits: int) -> int:
    value &= (1 << bits) - 1
    return value - (1 << bits) if value >> (bits - 1) else value


def fits(value: int, bits: int) -> bool:
    return -(1 << (bits - 1)) <= value < (1 << (bits - 1))


class Machine:
    """The engine's state, stepped one instruction (clock) at a time; see :func:`run`."""

    def __init__(self, prog: Program):
        self.p, self.w = prog, prog.widths
        self.mem = list(prog.mem_init)
        self.acc = self.cx = self.cy = self.cz = 0
        self.f = self.zero = self.back = self.down = self.roll = 0
        self.status = self.tag = 0
        self.pending = 0        # status bits of the previous instruction, ORed in one clock later
        self.ma = self.mb = self.la = self.lb = self.prod = 0
        self.rad = self.root = self.rem = 0

    def cond(self, ins) -> int:
        src = (1, self.f, self.back, self.down, self.roll, self.zero)
        a = src[ins.get("ca", 0)] ^ ins.get("cai", 0)
        b = src[ins.get("cb", 0)] ^ ins.get("cbi", 0)
        return a & b

    def bus(self, ins, mem_word, inputs) -> int:
        w = self.w
        sel = ins.get("bsel", 0)
        if sel == B_IN:
            return inputs[ins["iw"]] << w.guard
        return (mem_word, None, self.cx, self.cy, self.cz, self.root, self.rem, self.acc)[sel]

    def step(self, ins, mem_word, inputs, outputs):
        """One clock of ``ins`` (``mem_word``: the memory word read for it)."""
        w = self.w
        b = self.bus(ins, mem_word, inputs)
        cond = self.cond(ins)
        if ins.get("alu", 0) in ADDING and ins.get("bsel", 0) not in ADDER_SOURCES:
            raise ValueError(f"an adding ALU operation on B-bus source {ins.get('bsel')} "
                             f"(the adder takes {ADDER_SOURCES}) at {ins}")
        acc, f, event = self.acc, self.f, cond
        op = ins.get("alu", 0)
        if op in (A_CMPGT, A_CMPLT):
            event = 0
            if cond:
                f = event = int(acc > b if op == A_CMPGT else acc < b)
        elif op == A_SETF:
            f = cond
        elif op in (A_SATI, A_SATW):
            # Always clips; the condition gates only the status event.
            bits = w.internal if op == A_SATI else w.word
            lo, hi = -(1 << (bits - 1)), (1 << (bits - 1)) - 1
            clipped = min(hi, max(lo, acc))
            event = int(clipped != acc) & cond
            acc = clipped
        elif cond:
            shift = self.p.shifts[ins.get("sh", 0)]
            acc = {A_NOP: acc, A_LD: b, A_ADD: acc + b, A_SUB: acc - b, A_NEG: -acc,
                   A_SHR1: acc >> 1, A_SHR4: acc >> 4, A_SHR16: acc >> 16,
                   A_MLD: self.prod << shift, A_MACC: acc + (self.prod << shift)}[op]
        if not fits(acc, w.acc):
            raise OverflowError(f"accumulator overflow {acc} at {ins}")
        # Status bits reach the register one clock after their event (a register off the
        # compare's carry chain).
        status, self.pending = self.status | self.pending, ins.get("stat", 0) if event else 0
        # Memory write and word output take the accumulator before this instruction.
        if ins.get("wr"):
            if not fits(self.acc, w.mem):
                raise OverflowError(f"memory word overflow {self.acc} at {ins}")
            self.mem[ins["wa"]] = self.acc
        io = ins.get("io", 0)
        if io == IO_OUT:
            outputs[ins["iw"]] = wrap_signed(self.acc, w.word)
        elif io == IO_STATUS:
            outputs["status"], outputs["tag"] = self.status, self.tag
        elif io == IO_FLAGS:
            flags = inputs[len(INPUT_WORDS)]
            self.roll, self.back, self.down = flags & 1, (flags >> 1) & 1, (flags >> 2) & 1
            self.tag = flags >> 3
            status = 0
        self._cordic(ins, b, cond)
        self._multiply(ins, b)
        self._sqrt(ins)
        self.acc, self.f, self.status = acc, f, status

    def _cordic(self, ins, b, cond):
        w, op = self.w, ins.get("cop", 0)
        x, y, z = self.cx, self.cy, self.cz
        if op in (K_LDX, K_LDXG) and cond:
            x = b << (w.cordic_guard if op == K_LDXG else 0)
            z = 0 if op == K_LDXG else z
        elif op in (K_LDY, K_LDYG) and cond:
            y = b << (w.cordic_guard if op == K_LDYG else 0)
        elif op == K_LDZA and cond:
            z = b << w.angle_guard
        elif op in (K_COARSE, K_QROT):
            half = self.p.atan[-1]
            if op == K_COARSE:
                self.zero = int(x == 0 and y == 0)
                go, down = x < 0, y < 0
            else:
                go, down = self.f, z < 0          # rotation: turn towards z = 0
            if go:
                if down:
                    x, y, z = (-y, x, z - half) if op == K_COARSE else (y, -x, z + half)
                else:
                    x, y, z = (y, -x, z + half) if op == K_COARSE else (-y, x, z - half)
        elif op in (K_NORM8, K_NORM1):
            s = 8 if op == K_NORM8 else 1
            v = x | (~y if y < 0 else y)
            if v >> (w.internal - 1 - s + w.cordic_guard) == 0:
                x, y = x << s, y << s
        elif op in (K_VEC, K_ROT):
            i, step = ins.get("ci", 0), self.p.atan[ins.get("ci", 0)]
            # Vectoring turns by the sign of y, rotation drives z to 0.
            ccw = (y < 0) if op == K_VEC else (z >= 0)
            if ccw:
                x, y, z = x - (y >> i), y + (x >> i), z - step
            else:
                x, y, z = x + (y >> i), y - (x >> i), z + step
        for value, bits in ((x, w.xy), (y, w.xy), (z, w.z)):
            if not fits(value, bits):
                raise OverflowError(f"CORDIC register overflow {value} at {ins}")
        self.cx, self.cy, self.cz = x, y, z

    def _multiply(self, ins, b):
        w = self.w
        self.prod = self.la * self.lb            # the product register: two clocks after a pick
        if ins.get("pick"):
            self.la = (check_word(self.ma, w.check_lsb) if ins.get("pwa")
                       else limb(self.ma, ins.get("pa", 0), ins.get("psa", 0)))
            self.lb = (check_word(self.mb, w.check_lsb) if ins.get("pwb")
                       else limb(self.mb, ins.get("pb", 0), ins.get("psb", 0), w.b_limbs))
        mld = ins.get("mld", 0)
        if mld:
            if not fits(b, w.operand):
                raise OverflowError(f"multiplier operand overflow {b} at {ins}")
            if mld == 1:
                self.ma = b
            else:
                self.mb = b

    def _sqrt(self, ins):
        w, op = self.w, ins.get("sq", 0)
        if op == Q_LOAD:
            if not 0 <= self.acc < (1 << w.radicand):
                raise OverflowError(f"radicand out of range {self.acc}")
            self.rad, self.root, self.rem = self.acc, 0, 0
        elif op in (Q_STEP, Q_STEP2):
            for _ in range(op - Q_STEP + 1):
                self._digit()

    def _digit(self):
        """One digit of the square root (two radicand bits in, one root bit out)."""
        w = self.w
        rem = (self.rem << 2) | (self.rad >> (w.radicand - 2))
        self.rad = (self.rad << 2) & ((1 << w.radicand) - 1)
        trial = (self.root << 2) | 1
        if rem >= trial:
            self.rem, self.root = rem - trial, (self.root << 1) | 1
        else:
            self.rem, self.root = rem, self.root << 1


def run(prog: Program, inputs: list[int]) -> dict:
    """One pose through ``prog``: ``inputs`` are the 13 words of :data:`INPUT_WORDS` and the flags
    word (has_roll | shoulder_back << 1 | elbow_down << 2 | tag << 3). Returns the output words
    (0..4: q1..q5) and ``status``, ``tag``."""
    m = Machine(prog)
    outputs = {}
    code = prog.code
    # The memory read of instruction n happens two clocks ahead, in the clock of instruction
    # n - 2, before that instruction's write (see READ_AHEAD).
    reads = [m.mem[ins.get("rd", 0)] for ins in code[:READ_AHEAD]]
    for n, ins in enumerate(code):
        word = reads.pop(0)
        if n + READ_AHEAD < len(code):
            reads.append(m.mem[code[n + READ_AHEAD].get("rd", 0)])
        m.step(ins, word, inputs, outputs)
    return outputs
