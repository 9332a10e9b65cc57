"""The register map of the IK peripheral, written once as data.

The Amaranth Wishbone slave (``ik5r.hdl.soc.periph``) builds its decoder from :data:`REGISTERS`;
``ik5r_regs.h``, the LiteX-style ``csr.json``, the SVD and the README table are generated from it
by :mod:`ik5r.core.regmap_out`. Nothing here is typed twice.

Offsets are byte offsets from the peripheral's base, one 32-bit word per register (the bus is
word-addressed: byte offset = 4 x word address). Access types:

- ``RO``: read only; a write is acknowledged, ignored and sets ``EVENTS.RO_WRITE``.
- ``RW``: read and write; a write stores the bytes its SEL lanes select.
- ``W1C``: read; writing 1 to a bit clears it.

A field may have an action: ``pulse`` (writing 1 does something, reads 0) or ``pop`` (a read of
the register takes the result it shows off the result queue). Misuse, all acknowledged on the
next clock (the bus never waits):

- reading ``Q1``..``Q5`` while ``RESULT.VALID`` = 0 (no result yet): reads 0, nothing popped; a
  read of ``Q5`` (the popping read) then sets ``EVENTS.EMPTY_READ``;
- ``CTRL.START`` while the input register still holds a started pose (the core has not taken it):
  the start is dropped, ``EVENTS.OVERRUN`` set; otherwise a start while busy is queued;
- a write to an ``RO`` register: ignored, ``EVENTS.RO_WRITE`` set;
- an unmapped offset: reads 0, a write is ignored, ``EVENTS.UNMAPPED`` set.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass

from .modes import CoreArch

__all__ = ["Field", "Register", "REGISTERS", "ACCESS", "POSE_REGISTERS", "JOINT_REGISTERS",
           "ID_MAGIC", "CORE_KINDS", "BUILD_VALUES", "END", "TAG_BITS", "MAP_BYTES", "by_name", "id_values"]

ACCESS = ("RO", "RW", "W1C")
#: Bits of the tag the peripheral gives every started pose (a counter), returned with its result.
TAG_BITS = 8
#: "IK5R" in ASCII, the first ID word.
ID_MAGIC = 0x494B_3552
#: Core kinds in ``CORE.KIND``.
CORE_KINDS = {CoreArch.COMPACT: 0, CoreArch.PIPELINED: 1}
#: Bytes of address space the peripheral decodes (offsets at and beyond the last register are
#: unmapped up to here; the SoC decides what lies outside).
MAP_BYTES = 0x1000


@dataclass(frozen=True)
class Field:
    """``bits`` bits at ``lsb`` of a register; ``action``: '', 'pulse' or 'pop'."""

    name: str
    lsb: int
    bits: int
    description: str
    action: str = ""

    @property
    def mask(self) -> int:
        return ((1 << self.bits) - 1) << self.lsb


@dataclass(frozen=True)
class Register:
    """One 32-bit register at byte ``offset``."""

    name: str
    offset: int
    access: str
    description: str
    fields: tuple[Field, ...] = ()
    reset: int = 0

    def __post_init__(self):
        if self.access not in ACCESS or self.offset % 4 or not 0 <= self.offset < MAP_BYTES:
            raise ValueError(f"register {self.name}: bad access {self.access!r} or offset {self.offset}")
        used = 0
        for f in self.fields:
            if f.lsb < 0 or f.lsb + f.bits > 32 or used & f.mask:
                raise ValueError(f"register {self.name}: field {f.name} out of the word or overlapping")
            used |= f.mask


def _word(name: str, offset: int, what: str) -> Register:
    return Register(name, offset, "RW", f"{what}: a signed word of the config (the core takes the low W bits)")


POSE_REGISTERS = tuple(
    _word(name, 4 * i, what) for i, (name, what) in enumerate(
        [("PX", "tool point x, Q.frac_length cm"), ("PY", "tool point y, Q.frac_length cm"),
         ("PZ", "tool point z, Q.frac_length cm"), ("AX", "approach x, Q.frac_unit"),
         ("AY", "approach y, Q.frac_unit"), ("AZ", "approach z, Q.frac_unit"),
         ("NX", "normal x, Q.frac_unit"), ("NY", "normal y, Q.frac_unit"),
         ("NZ", "normal z, Q.frac_unit"), ("OX", "orientation x, Q.frac_unit"),
         ("OY", "orientation y, Q.frac_unit"), ("OZ", "orientation z, Q.frac_unit"),
         ("Q5_DEFAULT", "q5 without roll, Q.frac_angle rad")]))

JOINT_REGISTERS = tuple(
    Register(f"Q{j}", 0x3C + 4 * (j - 1), "RO",
             f"joint q{j} of the result at the head of the queue, Q.frac_angle rad, sign-extended"
             + ("; reading it pops that result" if j == 5 else ""),
             (Field("VALUE", 0, 32, f"q{j}", "pop" if j == 5 else ""),))
    for j in range(1, 6))

_EVENTS = (Field("DONE", 0, 1, "a result arrived (set with each result)"),
           Field("OVERRUN", 1, 1, "a start was dropped: the input register was still full"),
           Field("EMPTY_READ", 2, 1, "Q5 was read with no result in the queue (read 0)"),
           Field("RO_WRITE", 3, 1, "a write to a read-only register (ignored)"),
           Field("UNMAPPED", 4, 1, "an access to an unmapped offset (read 0, write ignored)"))

REGISTERS: tuple[Register, ...] = POSE_REGISTERS + (
    Register("CTRL", 0x34, "RW", "branch flags of the next start, and the start command",
             (Field("HAS_ROLL", 0, 1, "n, o given: q5 from the roll"),
              Field("SHOULDER_BACK", 1, 1, "tool point behind joint 1"),
              Field("ELBOW_DOWN", 2, 1, "q3 = -acos(c3)"),
              Field("START", 8, 1, "1: copy the pose and flags into the core's queue", "pulse"))),
    Register("RESULT", 0x38, "RO", "the result at the head of the queue and the queue's state",
             (Field("STATUS", 0, 6, "status bits of ik5r.core.status (IK5R_STATUS_*)"),
              Field("TAG", 8, TAG_BITS, "tag of the result: the count of starts before its own, mod 256"),
              Field("PENDING", 16, 12, "poses started and not popped (input register, core, queue)"),
              Field("BUSY", 30, 1, "a started pose has no result yet"),
              Field("VALID", 31, 1, "a result is at the head (done): Q1..Q5, STATUS, TAG hold it"))),
) + JOINT_REGISTERS + (
    Register("EVENTS", 0x50, "W1C", "sticky events; write 1 to clear", _EVENTS),
    Register("IRQ_ENABLE", 0x54, "RW", "interrupt enable: irq = DONE & RESULT.VALID",
             (Field("DONE", 0, 1, "interrupt while a result is at the head"),)),
    Register("ID", 0x58, "RO", "magic 'IK5R'", (Field("MAGIC", 0, 32, "0x494B3552"),), ID_MAGIC),
    Register("VERSION", 0x5C, "RO", "ik5r version of the generator",
             (Field("PATCH", 0, 8, "patch"), Field("MINOR", 8, 8, "minor"), Field("MAJOR", 16, 8, "major"))),
    Register("CONFIG_HASH", 0x60, "RO", "first 32 bits of SHA-256 of the fixed-point config's numbers",
             (Field("HASH", 0, 32, "hash"),)),
    Register("ARM_HASH", 0x64, "RO", "first 32 bits of SHA-256 of the arm's numbers",
             (Field("HASH", 0, 32, "hash"),)),
    Register("CORE", 0x68, "RO", "the core behind the bus",
             (Field("KIND", 0, 2, "0 compact (sequenced), 1 pipelined"),
              Field("WIDTH", 8, 6, "word width W of the config"),
              Field("CAPACITY", 16, 16, "poses the core holds (in flight and queued)"))),
)

#: Registers whose value is fixed per build (:func:`id_values`), not by reset.
BUILD_VALUES = ("VERSION", "CONFIG_HASH", "ARM_HASH", "CORE")
#: Byte offset just past the last register.
END = max(r.offset for r in REGISTERS) + 4


def by_name(name: str) -> Register:
    """The register called ``name`` (KeyError otherwise)."""
    for r in REGISTERS:
        if r.name == name:
            return r
    raise KeyError(name)


def _hash32(doc: dict) -> int:
    return int(hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()[:8], 16)


def id_values(constants, version: str, kind: str, capacity: int) -> dict[str, int]:
    """Reset values of the ID registers for a core of ``kind`` on ``constants`` (a
    :class:`ik5r.core.fxconfig.Constants`), generator ``version`` ('major.minor.patch')."""
    if kind not in CORE_KINDS:
        raise ValueError(f"kind must be one of {tuple(map(str, CORE_KINDS))}, got {kind!r}")
    major, minor, patch = (int(part) for part in (version.split(".") + ["0", "0"])[:3])
    cfg = {k: v for k, v in asdict(constants.cfg).items() if k not in ("name", "source")}
    arm = constants.arm.id_fields()
    return {"ID": ID_MAGIC, "VERSION": (major & 255) << 16 | (minor & 255) << 8 | (patch & 255),
            "CONFIG_HASH": _hash32(cfg), "ARM_HASH": _hash32(arm),
            "CORE": CORE_KINDS[kind] | constants.cfg.width << 8 | min(capacity, 0xFFFF) << 16}
