"""The clock-exact reference interpreter of the sequenced engine's programs (:mod:`.isa`).

:func:`run` executes a :class:`~.isa.Program` clock by clock, exactly as the hardware does (the
memory read of an instruction happens two clocks before it, the multiplier's two pipeline
registers), so it checks a program against ``model.ik_solve`` in milliseconds, before any HDL
simulation.
"""

from __future__ import annotations

import itertools

from ik5r.core.fxconfig import CHECK_BITS

from ..graph.inputs import INPUT_WORDS
from .isa import (ADDER_SOURCES, ADDING, FLAG_CONDITIONS, LIMB, READ_AHEAD, AluOp, BusSource,
                  CondSource, CordicOp, NORMS, SHIFTS, Ins, IoOp, MulLoad, Program, SqrtOp)

__all__ = ["Machine", "run", "run_poses", "run_stream", "limb", "check_word", "wrap_signed", "fits"]


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


def _alu_op(ins: Ins) -> AluOp:
    return ins.alu or AluOp.NOP


def _bsel(ins: Ins) -> BusSource:
    return ins.bsel or BusSource.MEM


class Machine:
    """The engine's state, stepped one instruction (clock) at a time; see :func:`run`."""

    def __init__(self, prog: Program):
        self.p, self.w = prog, prog.widths
        self.mem = list(prog.mem_init)
        self.acc = self.cx = self.cy = self.cz = 0
        self.f = self.zero = 0
        # A pose's registers, one per pose of the program (indexed by the pose fields).
        poses = prog.poses
        self.back, self.down, self.roll = [0] * poses, [0] * poses, [0] * poses
        self.status, self.tag = [0] * poses, [0] * poses
        self.pending = 0        # status bits of the previous instruction, ORed in one clock later
        self.pending_pose = 0
        self.ma = self.mb = self.la = self.lb = self.prod = 0
        self.rad = self.root = self.rem = 0

    #: The register each condition source reads (ONE: none, the constant 1). Tables built once:
    #: a table per instruction would hash every enum member on every clock.
    _COND_REGISTER = {CondSource.F: "f", CondSource.BACK: "back", CondSource.DOWN: "down",
                      CondSource.ROLL: "roll", CondSource.ZERO: "zero"}
    _BUS_REGISTER = {BusSource.CX: "cx", BusSource.CY: "cy", BusSource.CZ: "cz", BusSource.ROOT: "root",
                     BusSource.REM: "rem", BusSource.ACC: "acc"}

    def _source(self, src, pose: int) -> int:
        if src is None or src is CondSource.ONE:
            return 1
        value = getattr(self, self._COND_REGISTER[src])
        return value[pose] if src in FLAG_CONDITIONS else value

    def cond(self, ins: Ins) -> int:
        a = self._source(ins.ca, ins.cp or 0) ^ (ins.cai or 0)
        b = self._source(ins.cb, ins.cp or 0) ^ (ins.cbi or 0)
        return a & b

    def bus(self, ins: Ins, mem_word, inputs) -> int:
        sel = _bsel(ins)
        if sel is BusSource.IN:
            return inputs[ins.ip or 0][ins.iw] << self.w.guard
        return mem_word if sel is BusSource.MEM else getattr(self, self._BUS_REGISTER[sel])

    def step(self, ins: Ins, mem_word, inputs, outputs):
        """One clock of ``ins`` (``mem_word``: the memory word read for it; ``inputs``,
        ``outputs``: per pose of the program)."""
        w = self.w
        b = self.bus(ins, mem_word, inputs)
        cond = self.cond(ins)
        if _alu_op(ins) in ADDING and _bsel(ins) not in ADDER_SOURCES:
            raise ValueError(f"an adding ALU operation on B-bus source {ins.bsel} "
                             f"(the adder takes {ADDER_SOURCES}) at {ins}")
        acc, f, event = self._alu(ins, b, cond)
        if not fits(acc, w.acc):
            raise OverflowError(f"accumulator overflow {acc} at {ins}")
        # Status bits reach the register one clock after their event (a register off the
        # compare's carry chain).
        status = list(self.status)
        status[self.pending_pose] |= self.pending
        self.pending, self.pending_pose = (ins.stat or 0) if event else 0, ins.sp or 0
        # Memory write and word output take the accumulator before this instruction.
        if ins.wr:
            if not fits(self.acc, w.mem):
                raise OverflowError(f"memory word overflow {self.acc} at {ins}")
            self.mem[ins.wa] = self.acc
        self._io(ins, inputs, outputs, status)
        self._cordic(ins, b, cond)
        self._multiply(ins, b)
        self._sqrt(ins)
        self.acc, self.f, self.status = acc, f, status

    def _io(self, ins: Ins, inputs, outputs, status: list):
        """The word ports: an output word, the status word, the flags word (a pose's registers)."""
        pose = ins.ip or 0
        if ins.io == IoOp.OUT:
            outputs[pose][ins.iw] = wrap_signed(self.acc, self.w.word)
        elif ins.io == IoOp.STATUS:
            outputs[pose]["status"], outputs[pose]["tag"] = self.status[pose], self.tag[pose]
        elif ins.io == IoOp.FLAGS:
            flags = inputs[pose][len(INPUT_WORDS)]
            self.roll[pose], self.back[pose], self.down[pose] = flags & 1, (flags >> 1) & 1, (flags >> 2) & 1
            self.tag[pose] = flags >> 3
            status[pose] = 0

    def _alu(self, ins: Ins, b: int, cond: int) -> tuple:
        """(the accumulator, F, the status event) after the ALU operation of ``ins``."""
        acc, f, event, op = self.acc, self.f, cond, _alu_op(ins)
        if op in (AluOp.CMPGT, AluOp.CMPLT):
            event = 0
            if cond:
                f = event = int(acc > b if op == AluOp.CMPGT else acc < b)
        elif op == AluOp.SETF:
            f = cond
        elif op in SHIFTS:
            acc = acc >> self.p.acc_shifts[SHIFTS.index(op)] if cond else acc
        elif op in (AluOp.SATI, AluOp.SATW):
            # Always clips; the condition gates only the status event.
            bits = self.w.internal if op == AluOp.SATI else self.w.word
            lo, hi = -(1 << (bits - 1)), (1 << (bits - 1)) - 1
            clipped = min(hi, max(lo, acc))
            event = int(clipped != acc) & cond
            acc = clipped
        elif cond:
            acc = self._ARITHMETIC[op](acc, b, self.prod << self.p.shifts[ins.sh or 0])
        return acc, f, event

    #: The accumulator after an arithmetic operation: f(acc, B bus, the shifted product).
    _ARITHMETIC = {AluOp.NOP: lambda acc, b, prod: acc, AluOp.LD: lambda acc, b, prod: b,
                   AluOp.ADD: lambda acc, b, prod: acc + b, AluOp.SUB: lambda acc, b, prod: acc - b,
                   AluOp.NEG: lambda acc, b, prod: -acc,
                   AluOp.MLD: lambda acc, b, prod: prod, AluOp.MACC: lambda acc, b, prod: acc + prod}

    def _cordic(self, ins: Ins, b: int, cond: int):
        w, op = self.w, ins.cop or CordicOp.NOP
        x, y, z = self.cx, self.cy, self.cz
        if op in (CordicOp.LDX, CordicOp.LDXG) and cond:
            x = b << (w.cordic_guard if op == CordicOp.LDXG else 0)
            z = 0 if op == CordicOp.LDXG else z
        elif op in (CordicOp.LDY, CordicOp.LDYG) and cond:
            y = b << (w.cordic_guard if op == CordicOp.LDYG else 0)
        elif op == CordicOp.LDZA and cond:
            z = b << w.angle_guard
        elif op in (CordicOp.COARSE, CordicOp.QROT):
            x, y, z = self._quarter(op, x, y, z)
        elif op in NORMS:
            s = NORMS[op]
            v = x | (~y if y < 0 else y)
            if v >> (w.internal - 1 - s + w.cordic_guard) == 0:
                x, y = x << s, y << s
        elif op in (CordicOp.VEC, CordicOp.ROT):
            i, step = ins.ci or 0, self.p.atan[ins.ci or 0]
            # Vectoring turns by the sign of y, rotation drives z to 0.
            ccw = (y < 0) if op == CordicOp.VEC else (z >= 0)
            if ccw:
                x, y, z = x - (y >> i), y + (x >> i), z - step
            else:
                x, y, z = x + (y >> i), y - (x >> i), z + step
        for value, bits in ((x, w.xy), (y, w.xy), (z, w.z)):
            if not fits(value, bits):
                raise OverflowError(f"CORDIC register overflow {value} at {ins}")
        self.cx, self.cy, self.cz = x, y, z

    def _quarter(self, op: CordicOp, x: int, y: int, z: int) -> tuple:
        """The vectoring's coarse rotation or the rotation's quadrant step."""
        half = self.p.atan[-1]
        if op == CordicOp.COARSE:
            self.zero = int(x == 0 and y == 0)
            go, down = x < 0, y < 0
        else:
            go, down = self.f, z < 0          # rotation: turn towards z = 0
        if go:
            if down:
                return (-y, x, z - half) if op == CordicOp.COARSE else (y, -x, z + half)
            return (y, -x, z + half) if op == CordicOp.COARSE else (-y, x, z - half)
        return x, y, z

    def _multiply(self, ins: Ins, b: int):
        w = self.w
        self.prod = self.la * self.lb            # the product register: two clocks after a pick
        if ins.pick:
            self.la = (check_word(self.ma, w.check_lsb) if ins.pwa
                       else limb(self.ma, ins.pa or 0, ins.psa or 0))
            self.lb = (check_word(self.mb, w.check_lsb) if ins.pwb
                       else limb(self.mb, ins.pb or 0, ins.psb or 0, w.b_limbs))
        if ins.mld in (MulLoad.A, MulLoad.B):
            if not fits(b, w.operand):
                raise OverflowError(f"multiplier operand overflow {b} at {ins}")
            if ins.mld == MulLoad.A:
                self.ma = b
            else:
                self.mb = b

    def _sqrt(self, ins: Ins):
        if ins.sq == SqrtOp.LOAD:
            if not 0 <= self.acc < (1 << self.w.radicand):
                raise OverflowError(f"radicand out of range {self.acc}")
            self.rad, self.root, self.rem = self.acc, 0, 0
        elif ins.sq in (SqrtOp.STEP, SqrtOp.STEP2):
            for _ in range(2 if ins.sq == SqrtOp.STEP2 else 1):
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
    (0..4: q1..q5) and ``status``, ``tag`` (a program of several poses: the first, every pose
    given ``inputs``)."""
    return run_poses(prog, [inputs] * prog.poses)[0]


def run_poses(prog: Program, poses: list[list[int]]) -> list[dict]:
    """One run of ``prog``: ``poses`` its poses' input words (as :func:`run`'s), their outputs."""
    if len(poses) != prog.poses:
        raise ValueError(f"the program takes {prog.poses} poses a run, got {len(poses)}")
    if prog.cyclic:
        return run_stream(prog, poses)
    m = Machine(prog)
    inputs, outputs = poses, [{} for _ in poses]
    code = prog.code
    # The memory read of instruction n happens two clocks ahead, in the clock of instruction
    # n - 2, before that instruction's write (see READ_AHEAD).
    reads = [m.mem[ins.rd or 0] for ins in code[:READ_AHEAD]]
    for n, ins in enumerate(code):
        word = reads.pop(0)
        if n + READ_AHEAD < len(code):
            reads.append(m.mem[code[n + READ_AHEAD].rd or 0])
        m.step(ins, word, inputs, outputs)
    return outputs


def run_stream(prog: Program, poses: list[list[int]]) -> list[dict]:
    """``poses`` (input words as :func:`run`'s) through a cyclic program (:mod:`.modulo`), run
    after run as the engine runs it: a pose's first word takes the next pose if there is one,
    else the pose is skipped (its registers and words run on, nothing is offered), and the run
    stops at the first pose's first word when no pose is left and none is in flight. Returns
    the outputs in order."""
    m, code = Machine(prog), prog.code
    queue, results = list(poses), []
    inputs = [[0] * (len(INPUT_WORDS) + 1) for _ in range(prog.poses)]
    outputs = [{} for _ in range(prog.poses)]
    live = [False] * prog.poses
    reads = [m.mem[code[n % len(code)].rd or 0] for n in range(READ_AHEAD)]
    for n in itertools.count():
        ins = code[n % len(code)]
        pose = ins.ip or 0
        if ins.io == IoOp.IN and not ins.iw:
            if not queue and not any(live) and not pose:
                return results
            live[pose] = bool(queue)
            inputs[pose] = queue.pop(0) if queue else inputs[pose]
        word = reads.pop(0)
        reads.append(m.mem[code[(n + READ_AHEAD) % len(code)].rd or 0])
        m.step(ins, word, inputs, outputs)
        if ins.io == IoOp.STATUS and live[pose]:
            results.append(outputs[pose])
            outputs[pose], live[pose] = {}, False
