"""The word-serial wrapper of the compact IK core (``SerialIK`` in hdl/sequenced/serial.py) in the stream
testbench: a driver that serialises poses into beats and a monitor that reassembles words.

The wire format, as ``SerialIK`` documents it, with ``W`` the word width, ``T`` the tag width and
``b`` the beat width: per pose 14 input words, each ``ceil(max(W, 3 + T) / b)`` beats, least
significant beat first: px, py, pz, ax, ay, az, nx, ny, nz, ox, oy, oz, q5_default (two's
complement in W bits), then the flags word has_roll | shoulder_back << 1 | elbow_down << 2 |
tag << 3. Per pose 6 output words of ``ceil(max(W, S + T) / b)`` beats: q1..q5 (W bits), then
status | tag << S (S status bits); every bit above a word's fields must be 0, and is checked.

The testbench keeps the word-level view of the compact core (:func:`word_portmap`: its fields, the
wrapper's timing) for stimulus, model and scoreboard: a pose is pending once its last input beat is
taken, and produced with its last output beat; latency runs from its first input beat to its last
output beat (the wrapper's ``latency``). A reset drops the beats of a pose half sent (it is sent
again, with a new tag) and of results half received.
"""

from __future__ import annotations

from dataclasses import dataclass

from .components import Driver, Monitor
from .portmap import PortMap

#: Input words in wire order (then the flags word); output words q1..q5 (then the status word).
IN_WORDS = ("px", "py", "pz", "ax", "ay", "az", "nx", "ny", "nz", "ox", "oy", "oz", "q5_default")
OUT_WORDS = ("q1", "q2", "q3", "q4", "q5")
FLAG_BITS = (("has_roll", 0), ("shoulder_back", 1), ("elbow_down", 2))


def _ceil_div(a: int, b: int) -> int:
    return -(-a // b)


@dataclass(frozen=True)
class SerialFormat:
    """Beats per word of the wrapper, from the compact core's word-level port map."""

    beat_bits: int
    word_bits: int          # W
    status_bits: int        # S
    tag_bits: int           # T (0: no tag field)

    @classmethod
    def of(cls, pm: PortMap, beat_bits: int) -> SerialFormat:
        tag = pm.tag_field
        return cls(beat_bits, pm.i.fields["px"].width, pm.o.fields["status"].width,
                   pm.o.fields[tag].width if tag else 0)

    @property
    def in_beats(self) -> int:
        return _ceil_div(max(self.word_bits, 3 + self.tag_bits), self.beat_bits)

    @property
    def out_beats(self) -> int:
        return _ceil_div(max(self.word_bits, self.status_bits + self.tag_bits), self.beat_bits)

    def split(self, word: int, beats: int) -> list[int]:
        mask = (1 << self.beat_bits) - 1
        return [(word >> (self.beat_bits * j)) & mask for j in range(beats)]

    def input_beats(self, values: dict[str, int], tag: str | None) -> list[int]:
        """The beats of one pose (its fields by name, the tag under ``tag``)."""
        word_mask = (1 << self.word_bits) - 1
        words = [values[name] & word_mask for name in IN_WORDS]
        flags = sum((values[name] & 1) << bit for name, bit in FLAG_BITS)
        words.append(flags | ((values[tag] << 3) if tag else 0))
        return [beat for word in words for beat in self.split(word, self.in_beats)]

    def output_item(self, beats: list[int], tag: str | None) -> tuple[dict[str, int], str | None]:
        """(fields, problem) of one pose's output beats; the problem names any bit set above a
        word's fields (None if there is none)."""
        n = self.out_beats
        words = [sum(beat << (self.beat_bits * j) for j, beat in enumerate(beats[w * n:(w + 1) * n]))
                 for w in range(len(OUT_WORDS) + 1)]
        values, problems = {}, []
        for name, word in zip(OUT_WORDS, words):
            raw = word & ((1 << self.word_bits) - 1)
            values[name] = raw - (1 << self.word_bits) if raw >> (self.word_bits - 1) else raw
            if word >> self.word_bits:
                problems.append(f"{name} word 0x{word:x}: bits above {self.word_bits} set")
        status = words[-1]
        values["status"] = status & ((1 << self.status_bits) - 1)
        used = self.status_bits + self.tag_bits
        if tag:
            values[tag] = (status >> self.status_bits) & ((1 << self.tag_bits) - 1)
        if status >> used:
            problems.append(f"status word 0x{status:x}: bits above {used} set")
        return values, "; ".join(problems) or None


class BeatDriver(Driver):
    """Sends each queued pose as its beats: random idle cycles before any beat (when the driver's
    idles are on), each beat held until taken. A pose joins the scoreboard with its last beat, as
    accepted in the cycle of its first (the wrapper's latency runs from the first input beat to
    the last output beat)."""

    def __init__(self, dut, job, rng):
        super().__init__(dut, job, rng)
        self.fmt = SerialFormat.of(job.pm, int(job.serial["beat_bits"]))
        self.beats: list[int] = []      # the beats of the pose on offer
        self.next_beat = 0
        self.first_beat_cycle = 0
        self.on_bus = False             # a beat is on the bus
        self.beats_dropped = 0          # beats of poses half sent when a reset came

    def drive(self, in_reset: bool):
        if in_reset:
            self.valid.value = 0
            return
        if not self.on_bus and (self.offering is not None or self.queue) and not self._pause():
            if self.offering is None:
                index = self.queue.popleft()
                self.offering = (index, self.seq)
                self.seq += 1
                self.beats = self.fmt.input_beats(self.values(*self.offering), self.job.tag)
                self.next_beat = 0
            self.payload.value = self.beats[self.next_beat]
            self.on_bus = True
        self.valid.value = 1 if self.on_bus else 0

    def sample(self, cycle: int, in_reset: bool):
        if self.on_bus and not in_reset and self.ready.value == 1:
            self.on_bus = False
            if self.next_beat == 0:
                self.first_beat_cycle = cycle
            self.next_beat += 1
            if self.next_beat == len(self.beats):
                index, seq = self.offering
                self.accepted.append((self.first_beat_cycle, index, seq))
                self.on_accept(self.first_beat_cycle, index, seq)
                self.offering = None

    def requeue(self, items):
        """As :meth:`Driver.requeue`; the pose half sent starts again from its first beat."""
        if self.offering is not None:
            self.beats_dropped += self.next_beat
        self.on_bus = False
        super().requeue(items)


class BeatMonitor(Monitor):
    """Collects the taken output beats (the stream rule checked per beat) and hands each pose's
    reassembled words to the scoreboard; a reset drops the beats of a pose half received."""

    def __init__(self, dut, job, bp, fault=None):
        super().__init__(dut, job, bp, fault)
        self.fmt = SerialFormat.of(job.pm, int(job.serial["beat_bits"]))
        self.tag = job.tag
        self.beats: list[int] = []
        self.beats_dropped = 0          # beats of results half received when a reset came

    def sample(self, cycle: int, in_reset: bool):
        if in_reset:
            self.beats_dropped += len(self.beats)
            self.beats.clear()
        super().sample(cycle, in_reset)

    def describe(self, value: int) -> dict:
        return {"beat": value, "beats_of_pose_so_far": len(self.beats)}

    def take(self, cycle: int, value: int):
        self.beats.append(value)
        if len(self.beats) == self.fmt.out_beats * (len(OUT_WORDS) + 1):
            values, problem = self.fmt.output_item(self.beats, self.tag)
            self.beats = []
            if problem:
                self.callback(cycle, None, problem, "padding")
            else:
                self.callback(cycle, values, None)


def word_portmap(beat_map: dict, k, tag_width: int) -> dict:
    """The testbench's word-level port map of the serial wrapper: the wrapper's own (``beat_map``:
    module, timing, arm, config) with the compact core's streams and ports, from the core's payload
    fields alone (no core is built: that would compile its program, a schedule search), and the
    beat width (``serial``)."""
    from ik5r.hdl.generate import stream_ports
    from ik5r.hdl.graph.inputs import tagged_fields

    ports, streams = stream_ports(*tagged_fields(k, tag_width))
    doc = dict(beat_map, ports=ports, streams=streams, options={})
    doc["serial"] = {"beat_bits": beat_map["options"]["serial"]}
    return doc
