"""The micro-instruction set of the sequenced IK engine (:mod:`.engine`): the instruction, its
operands and its word.

An instruction (:class:`Ins`) sets fields (absent = ``None``, encoded 0), one field group per
unit, all acting in the same clock: the data memory (one read ``rd``, one write ``wa`` of the
accumulator as it was before the instruction), the accumulator ALU (``alu``, condition
``ca/cai & cb/cbi``, status mask ``stat``), the CORDIC micro-rotation unit (``cop``, step ``ci``),
the multiplier (``mld`` operand loads, ``pick`` of one 16 x 16 limb product, or of a product of
check words, the top :data:`~ik5r.core.fxconfig.CHECK_BITS` bits of an internal word, ``pwa`` /
``pwb``; two clocks later accumulated by ``MACC`` / ``MLD``), the digit-serial square root
(``sq``) and the word ports (``io``). The program is straight-line (no branches: selections are
conditional ALU and CORDIC operations), so a pose takes exactly the program's length in clocks,
plus any wait on the word ports (a cyclic program's, :mod:`.modulo`, up to two lengths: its
poses run on into the next run).

A field that is present claims its unit even at its zero value (an ``ALU.NOP`` with a status
event, a pick of limb 0): the scheduler (:mod:`.schedule`) merges instructions whose present
fields are disjoint. :func:`word_layout` is the instruction word (``lib.data.StructLayout``, one
field per instruction field, enum fields for the operations), :func:`encode` the one place an
instruction becomes a word. The clock-exact reference interpreter is :mod:`.machine`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace

from amaranth.hdl import unsigned
from amaranth.lib import data, enum

from ..graph.inputs import BranchFlag


class BusSource(enum.Enum, shape=3):
    """B-bus sources (``bsel``): memory word, input word (<< guard), CORDIC x / y / z, root,
    remainder, the accumulator itself."""
    MEM, IN, CX, CY, CZ, ROOT, REM, ACC = range(8)


class AluOp(enum.Enum, shape=4):
    """Accumulator operations (``alu``); ``SHRA``, ``SHRB``, ``SHRC``: arithmetic shifts right by
    the program's three amounts (:attr:`Program.acc_shifts`)."""
    NOP, LD, ADD, SUB, NEG, CMPGT, CMPLT, SHRA, SHRB, SHRC, SATI, SATW, MLD, MACC, SETF = range(15)


class CondSource(enum.Enum, shape=3):
    """Condition sources (``ca``, ``cb``; ``cai``, ``cbi`` invert): always, F, shoulder_back,
    elbow_down, has_roll, CORDIC zero vector."""
    ONE, F, BACK, DOWN, ROLL, ZERO = range(6)


class CordicOp(enum.Enum, shape=4):
    """CORDIC operations (``cop``): loads from the B bus (x, y; ``G``: shifted up by the CORDIC
    guard bits, x also clears z; z shifted up by the angle guard bits), the vectoring coarse
    rotation (by -+90 degrees if x < 0; latches the zero-vector flag), the rotation quadrant step
    (by -+90 degrees if F), the conditional normalising shifts (``NORMn``: x and y by n bits if
    both fit, :data:`NORMS`), and micro-rotation ``ci`` (vectoring or rotation)."""
    NOP, LDX, LDY, LDXG, LDYG, LDZA, COARSE, QROT, NORM8, NORM1, VEC, ROT = range(12)
    # 12 and 13 are free: the code of NORM2 changes how the x and y registers' muxes map to
    # LUTs (this one: 3,324 LUT4 and 85-88 MHz over five nextpnr seeds; 12: 3,498 and 78-80).
    NORM2 = 14


class MulLoad(enum.Enum, shape=2):
    """Multiplier operand loads (``mld``): none, MA, MB (from the B bus)."""
    NONE, A, B = range(3)


class SqrtOp(enum.Enum, shape=2):
    """Square root (``sq``): load the radicand from the accumulator, one digit step, two."""
    NOP, LOAD, STEP, STEP2 = range(4)


class IoOp(enum.Enum, shape=3):
    """Word ports (``io``): input word ``iw`` on the B bus, the flags word (ends the input),
    output word ``iw`` (the accumulator, before this instruction), the status word (ends the
    output)."""
    NOP, IN, FLAGS, OUT, STATUS = range(5)


# The assembler's mnemonics (the lowering, :mod:`.lower`, writes its blocks with them).
B_MEM, B_IN, B_CX, B_CY, B_CZ, B_ROOT, B_REM, B_ACC = BusSource
(A_NOP, A_LD, A_ADD, A_SUB, A_NEG, A_CMPGT, A_CMPLT, A_SHRA, A_SHRB, A_SHRC, A_SATI, A_SATW,
 A_MLD, A_MACC, A_SETF) = AluOp
C_ONE, C_F, C_BACK, C_DOWN, C_ROLL, C_ZERO = CondSource
(K_NOP, K_LDX, K_LDY, K_LDXG, K_LDYG, K_LDZA, K_COARSE, K_QROT, K_NORM8, K_NORM1, K_VEC,
 K_ROT, K_NORM2) = CordicOp
Q_NOP, Q_LOAD, Q_STEP, Q_STEP2 = SqrtOp
IO_NOP, IO_IN, IO_FLAGS, IO_OUT, IO_STATUS = IoOp

#: The accumulator's shifts right (three ops, their amounts chosen per program:
#: :func:`.shifts.acc_shifts_for`) and the CORDIC's normalising shifts left
#: (:meth:`.asm.Asm.atan2_body`), by their bits. Three normalising shifts (8, 2, 1: M bits in
#: M // 8 + 4 clocks at most) rather than five (16, 8, 4, 2, 1: about log2(M)): each shift is an
#: option of the x and y registers' mux, on the micro-rotation's path; the two more cost more
#: LUTs and clock than their few clocks are worth. A fourth shift of the accumulator would put
#: its wide result mux a level deeper: more LUTs than the clocks are worth. (The figures: the
#: commits that made these choices.)
SHIFTS = (A_SHRA, A_SHRB, A_SHRC)
NORMS = {K_NORM1: 1, K_NORM2: 2, K_NORM8: 8}

#: The B-bus sources an adding ALU operation (``ADDING``) may take: the adder has its own operand
#: select of these few registers, off the B bus (the input word's and the CORDIC's paths through
#: the B bus into the adder's carry chain were the engine's slowest). Other sources are loaded
#: (``LD``, the CORDIC and multiplier loads).
ADDING = (A_ADD, A_SUB, A_CMPGT, A_CMPLT)
ADDER_SOURCES = (B_MEM, B_ROOT, B_ACC)

#: The condition source of each branch flag of the traced graph.
FLAG_SOURCE = {BranchFlag.ROLL: C_ROLL, BranchFlag.BACK: C_BACK, BranchFlag.DOWN: C_DOWN}

#: Clocks between an instruction's memory read and its execution: a store is seen by
#: instructions at least READ_AHEAD + 1 after it.
READ_AHEAD = 2
LIMB = 15          # unsigned limb bits; the top limb of an operand is 16 bits, signed


@dataclass(frozen=True)
class Var:
    """A memory operand: the word of a variable (an address once :meth:`.asm.Asm.finish` ran)."""
    name: str


@dataclass(frozen=True)
class Const:
    """A memory operand: a word of the data memory's constant pool."""
    value: int

    def __post_init__(self):
        object.__setattr__(self, "value", int(self.value))


@dataclass(frozen=True)
class Ins:
    """One instruction (see the module docstring); a field is ``None`` when absent. ``rd`` and
    ``wa`` are :class:`Var` / :class:`Const` operands until the program's addresses are
    resolved, then addresses."""
    rd: Var | Const | int | None = None
    bsel: BusSource | None = None
    wr: int | None = None
    wa: Var | int | None = None
    alu: AluOp | None = None
    ca: CondSource | None = None
    cai: int | None = None
    cb: CondSource | None = None
    cbi: int | None = None
    stat: int | None = None
    sh: int | None = None
    cop: CordicOp | None = None
    ci: int | None = None
    mld: MulLoad | None = None
    pick: int | None = None
    pa: int | None = None
    pb: int | None = None
    psa: int | None = None
    psb: int | None = None
    pwa: int | None = None
    pwb: int | None = None
    sq: SqrtOp | None = None
    io: IoOp | None = None
    iw: int | None = None
    ip: int | None = None
    sp: int | None = None
    cp: int | None = None

    def present(self) -> frozenset:
        """The names of the fields this instruction sets."""
        return frozenset(self.set_fields())

    def merge(self, other: "Ins") -> "Ins":
        """This instruction with ``other``'s present fields set (they win)."""
        return Ins(**{**self.set_fields(), **other.set_fields()})

    def set_fields(self) -> dict:
        """{name: value} of the fields this instruction sets, in word order."""
        return {name: value for name in FIELDS if (value := getattr(self, name)) is not None}


#: The instruction fields in word order (the first at bit 0).
FIELDS = tuple(f.name for f in fields(Ins))
#: The pose (of a program of several, :func:`.program.interleave`) whose registers a field group
#: acts on: ``ip`` the word port's (``io``: the pose's inputs, flags, outputs and status), ``sp``
#: the status event's (``stat``), ``cp`` the flag conditions' (``ca``, ``cb`` on BACK, DOWN,
#: ROLL). Absent (pose 0) in a one-pose program: no bits in its word.
POSE_FIELDS = ("ip", "sp", "cp")
FLAG_CONDITIONS = (CondSource.BACK, CondSource.DOWN, CondSource.ROLL)


def pose_of(ins: Ins, pose: int) -> Ins:
    """``ins`` as an instruction of pose ``pose`` (pose 0: itself): its variables the pose's
    own words, its pose fields set where it acts on a pose's registers."""
    if pose == 0:
        return ins

    def own(ref):
        return Var(f"p{pose}.{ref.name}") if isinstance(ref, Var) else ref

    flagged = ins.ca in FLAG_CONDITIONS or ins.cb in FLAG_CONDITIONS
    return replace(ins, rd=own(ins.rd), wa=own(ins.wa), ip=pose if ins.io is not None else None,
                   sp=pose if ins.stat is not None else None, cp=pose if flagged else None)
#: The enum type of each operation field; the others are unsigned numbers.
ENUM_FIELDS = {"bsel": BusSource, "alu": AluOp, "ca": CondSource, "cb": CondSource,
               "cop": CordicOp, "mld": MulLoad, "sq": SqrtOp, "io": IoOp}



def nonzero(value) -> bool:
    """A field that is present and not its zero (an enum's NOP / NONE member, or 0)."""
    return bool(value.value if isinstance(value, enum.Enum) else value)


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
    """A straight-line program (its addresses resolved), its data memory image and table ROM,
    and the engine's widths."""

    code: list[Ins]
    mem_init: list           # memory words (constants; variables 0)
    atan: list               # CORDIC step angles by ``ci`` (last entry: half pi)
    shifts: list             # MACC / MLD shift amounts by ``sh``
    widths: Widths
    names: dict = field(default_factory=dict)   # variable name -> address
    poses: int = 1           # poses per run of the code (:func:`.program.interleave`)
    cyclic: bool = False     # poses run on into the next run (a modulo schedule, :mod:`.modulo`)
    acc_shifts: tuple = (1, 4, 16)  # bits of the accumulator's shifts right by SHIFTS' ops


def _number(ins: Ins, name: str) -> int:
    value = getattr(ins, name)
    if value is None:
        return 0
    if not isinstance(value, int):
        raise TypeError(f"field {name} of {ins} is {value!r}, not a number (unresolved operand?)")
    return value


def word_layout(code: list[Ins]) -> data.StructLayout:
    """The instruction word of a program: the operation fields their enums, every other field
    as many bits as its largest value in ``code`` needs (at least 1)."""
    return data.StructLayout({
        name: ENUM_FIELDS.get(name) or unsigned(max(1, max(_number(i, name) for i in code).bit_length()))
        for name in FIELDS if name not in POSE_FIELDS or any(getattr(i, name) for i in code)})


def encode(layout: data.StructLayout, ins: Ins) -> data.Const:
    """The word of ``ins`` in ``layout`` (an absent field is 0)."""
    return layout.const({name: getattr(ins, name) if name in ENUM_FIELDS else _number(ins, name)
                         for name in ins.present()})


def read_write_clash(code: list[Ins]) -> int | None:
    """The first instruction that writes the memory word read in the same clock (for the
    instruction READ_AHEAD later; the program repeats, so past its end from its start), or
    None. The engine's memory leaves such a collision undefined (no bypass logic)."""
    for index, ins in enumerate(code):
        reader = code[(index + READ_AHEAD) % len(code)]
        if ins.wr and _number(ins, "wa") == _number(reader, "rd"):
            return index
    return None
