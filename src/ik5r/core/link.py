"""The framed binary protocol of the board link (docs/protocol.md): framing, CRC, payloads.

One codec for both ends: the host client (:mod:`ik5r.tools.boardlink`) encodes poses and parses
the board's frames with it, and the HDL tests use it as the reference model of the board's frame
decoder and encoder (:mod:`ik5r.hdl.board`).

A frame is ``SYNC, type, length, tag, payload, crc_hi, crc_lo``: ``length`` 32-bit payload words,
each little-endian; the CRC-16/CCITT-FALSE (polynomial 0x1021, init 0xFFFF, not reflected, no
final xor) of every byte from ``type`` to the end of the payload, most significant byte first,
so the CRC of ``type .. crc_lo`` is 0.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

from .modes import BoardCore

SYNC = 0xA5
HEADER_BYTES = 4      # sync, type, length, tag
CRC_BYTES = 2
WORD_BYTES = 4

#: Frame types (host -> board: POSE, ID with no payload = a request; board -> host: the rest).
POSE, JOINTS, ID, ERROR = 0x01, 0x02, 0x03, 0x04
TYPE_NAMES = {POSE: "pose", JOINTS: "joints", ID: "id", ERROR: "error"}

#: Payload words: a pose is 12 vector words, the q5 default, the flags word (has_roll |
#: shoulder_back << 1 | elbow_down << 2); joints are q1..q5 and the status bits.
POSE_WORDS = 14
JOINT_WORDS = 6
#: ID payload: protocol version, ik5r version, config hash, arm hash, core, clock (Hz), baud,
#: credits (poses the host may have in flight).
ID_FIELDS = ("protocol", "version", "config_hash", "arm_hash", "core", "clock_hz", "baud", "credits")
PROTOCOL_VERSION = 1
#: Core codes of the ID frame.
CORES = {BoardCore.SERIAL: 1, BoardCore.COMPACT: 2, BoardCore.PIPELINED: 3}

#: Error codes (the error frame's one payload word; its tag is the damaged frame's, 0 if unknown).
E_CRC, E_TYPE, E_LENGTH, E_TIMEOUT, E_OVERFLOW = 1, 2, 3, 4, 5
ERROR_NAMES = {E_CRC: "crc", E_TYPE: "unknown type", E_LENGTH: "bad length",
               E_TIMEOUT: "truncated (timeout)", E_OVERFLOW: "receive buffer overflow"}


def crc16(data: bytes, crc: int = 0xFFFF) -> int:
    """CRC-16/CCITT-FALSE of ``data`` (check value of b"123456789": 0x29B1)."""
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else crc << 1
            crc &= 0xFFFF
    return crc


def encode(kind: int, tag: int, words=()) -> bytes:
    """One frame: ``words`` as 32-bit two's-complement words, little-endian."""
    words = list(words)
    if not 0 <= kind <= 255 or not 0 <= tag <= 255 or len(words) > 255:
        raise ValueError(f"type {kind}, tag {tag}, {len(words)} words: out of range")
    body = bytes([kind, len(words), tag]) + b"".join(
        (int(w) & 0xFFFFFFFF).to_bytes(WORD_BYTES, "little") for w in words)
    crc = crc16(body)
    return bytes([SYNC]) + body + bytes([crc >> 8, crc & 0xFF])


def frame_bytes(words: int) -> int:
    return HEADER_BYTES + WORD_BYTES * words + CRC_BYTES


def signed32(word: int) -> int:
    return word - (1 << 32) if word & 0x80000000 else word


@dataclass(frozen=True)
class Frame:
    kind: int
    tag: int
    words: tuple

    def signed(self, index: int) -> int:
        return signed32(self.words[index])


class Parser:
    """Frames out of a byte stream. A frame whose CRC fails is skipped from its sync byte on (the
    next sync byte may start a good frame): the host end resynchronises by itself. ``dropped``
    counts the bytes skipped."""

    def __init__(self):
        self.buffer = bytearray()
        self.dropped = 0

    def feed(self, data: bytes) -> list[Frame]:
        self.buffer += data
        frames = []
        while True:
            start = self.buffer.find(SYNC)
            if start < 0:
                self.dropped += len(self.buffer)
                self.buffer.clear()
                return frames
            if start:
                self.dropped += start
                del self.buffer[:start]
            if len(self.buffer) < HEADER_BYTES:
                return frames
            total = frame_bytes(self.buffer[2])
            if len(self.buffer) < total:
                return frames
            if crc16(bytes(self.buffer[1:total])) != 0:
                self.dropped += 1
                del self.buffer[:1]
                continue
            words = tuple(int.from_bytes(self.buffer[HEADER_BYTES + WORD_BYTES * i:
                                                     HEADER_BYTES + WORD_BYTES * (i + 1)], "little")
                          for i in range(self.buffer[2]))
            frames.append(Frame(self.buffer[1], self.buffer[3], words))
            del self.buffer[:total]


def pose_frame(tag: int, vector_words, q5_default: int, roll: bool, back: bool, down: bool) -> bytes:
    """A pose frame: 12 words p, a, n, o (the IK core's input words), q5 default, flags."""
    flags = int(bool(roll)) | int(bool(back)) << 1 | int(bool(down)) << 2
    return encode(POSE, tag, [*vector_words, q5_default, flags])


def short_hash(text: str) -> int:
    """The 32-bit hash of the ID frame: the first 4 bytes of SHA-256, big-endian."""
    return int.from_bytes(hashlib.sha256(text.encode()).digest()[:4], "big")


def config_hash(constants) -> int:
    """The ID frame's config hash: the config's numbers (not its name or path)."""
    from dataclasses import asdict

    cfg = {k: v for k, v in asdict(constants.cfg).items() if k not in ("name", "source")}
    return short_hash(repr(sorted(cfg.items())))


def arm_hash(constants) -> int:
    """The ID frame's arm hash: the arm's numbers (not its name); a board built with --arm
    differs here."""
    return short_hash(repr(sorted(constants.arm.id_fields().items())))


def version_word(version: str) -> int:
    """major << 16 | minor << 8 | patch of a version string (missing parts 0)."""
    parts = [int("".join(ch for ch in p if ch.isdigit()) or 0) for p in version.split(".")[:3]]
    parts += [0] * (3 - len(parts))
    return (parts[0] & 0xFF) << 16 | (parts[1] & 0xFF) << 8 | (parts[2] & 0xFF)
