"""cocotb-driven components of the stream testbench (:mod:`.stream_tb`), in the shape of cocotb's
matrix_multiplier example: a :class:`Driver` offers items with random idle cycles between them, a
:class:`BackPressure` generator drives ``o.ready`` (random, with long stalls of 50-200 cycles), a
:class:`Monitor` samples accepted outputs into an in-order :class:`Scoreboard`, and a
:class:`ResetGen` asserts the reset in the middle of traffic: items in flight are flushed (and sent
again afterwards), any output of a flushed item afterwards is a stale-output error.

:class:`StreamTB` steps them all from one clocked loop in a fixed order per cycle (drive after the
falling edge, sample in ReadOnly), which is deterministic on every simulator and costs two triggers
per clock. The word-serial variants of the driver and the monitor are in :mod:`.serial`.
"""

from __future__ import annotations

import os
import random
from collections import deque

from cocotb.triggers import FallingEdge, ReadOnly

from .job import Job, Results


def _sig(dut, name):
    return dut[name]


# ---- cocotb-driven components -------------------------------------------------------------------

class Driver:
    """Offers queued items on the input stream; random idle cycles between items (a pause
    generator as in cocotbext-axi); holds valid/payload until accepted; valid low in reset."""

    def __init__(self, dut, job: Job, rng: random.Random):
        pm = job.pm
        self.valid = _sig(dut, pm.i.valid)
        self.ready = _sig(dut, pm.i.ready)
        self.payload = _sig(dut, pm.i.payload)
        self.stream = pm.i
        self.job = job
        self.rng = rng
        self.queue: deque[int] = deque()    # vector indices to send, in order
        self.inputs = None                  # role -> array
        self.seq = 0                        # running tag counter
        self.idle_prob = 0.0
        self.idle_max = 0
        self._idle = 0
        self.offering = None                # (index, seq) currently on the bus
        self.accepted = []                  # (cycle, index, seq)
        self.on_accept = None

    def values(self, index: int, seq: int) -> dict[str, int]:
        """The payload fields of item ``index`` sent with tag ``seq``."""
        values = {self.job.bind_in[r]: int(v[index]) for r, v in self.inputs.items()}
        if self.job.tag:
            values[self.job.tag] = seq % self.job.tag_mod
        return values

    def word(self, index: int, seq: int) -> int:
        return self.stream.pack(self.values(index, seq))

    def _pause(self) -> bool:
        """True in an idle cycle: one left of a pause, or a new pause of 1 + 0..idle_max cycles."""
        if self._idle > 0:
            self._idle -= 1
            return True
        if self.idle_prob and self.rng.random() < self.idle_prob:
            self._idle = self.rng.randint(0, self.idle_max)
            return True
        return False

    def drive(self, in_reset: bool):
        if in_reset:
            self.valid.value = 0
            return
        if self.offering is None and self.queue and not self._pause():
            index = self.queue.popleft()
            self.offering = (index, self.seq)
            self.seq += 1
            self.payload.value = self.word(*self.offering)
        self.valid.value = 1 if self.offering is not None else 0

    def sample(self, cycle: int, in_reset: bool):
        if self.offering is not None and not in_reset and self.ready.value == 1:
            index, seq = self.offering
            self.accepted.append((cycle, index, seq))
            self.on_accept(cycle, index, seq)
            self.offering = None

    def requeue(self, items):
        """Put items (indices) back at the front, ahead of the one on the bus (which is dropped and
        offered again with a new tag)."""
        if self.offering is not None:
            self.queue.appendleft(self.offering[0])
            self.offering = None
        self.queue.extendleft(reversed(list(items)))


class BackPressure:
    """Drives o.ready: always ready, or random with long stalls of 50-200 cycles."""

    def __init__(self, dut, job: Job, rng: random.Random):
        self.ready = _sig(dut, job.pm.o.ready)
        self.rng = rng
        self.mode = "always"
        self.ready_prob = 0.7
        self.stall_prob = 0.004
        self._stall = 0
        self.value = 1

    def drive(self):
        if self.mode == "always":
            self.value = 1
        elif self._stall > 0:
            self._stall -= 1
            self.value = 0
        elif self.rng.random() < self.stall_prob:
            self._stall = self.rng.randint(50, 200)
            self.value = 0
        else:
            self.value = 1 if self.rng.random() < self.ready_prob else 0
        self.ready.value = self.value


class Monitor:
    """Samples accepted output items (o.valid & o.ready, reset low) and hands them on; checks the
    stream rule on the output: an item offered and not taken (o.valid & ~o.ready) is offered
    again, unchanged, in the next cycle (also when that cycle asserts the reset: the reset acts on
    the clock edge after it and only then releases the item).

    ``fault`` (the testbench self-test) corrupts the monitor's view: ``{"kind": "flip", "at": n}``
    flips bit 0 (or ``"bit": b``) of the n-th taken payload, ``"drop"`` swallows the n-th taken
    item (a lost tag), ``"unstable"`` flips bit 0 of the payload in the n-th held cycle."""

    def __init__(self, dut, job: Job, bp: BackPressure, fault: dict | None = None):
        self.valid = _sig(dut, job.pm.o.valid)
        self.payload = _sig(dut, job.pm.o.payload)
        self.stream = job.pm.o
        self.bp = bp
        self.first_valid = None
        self.callback = None
        self.on_hold_violation = None
        self.held = None            # payload offered and not taken in the previous cycle
        self.held_cycles = 0        # cycles in which the rule was checked
        self.taken = 0
        self.fault = fault or {}

    def _payload(self, value: int, held: bool) -> int:
        kind, at = self.fault.get("kind"), int(self.fault.get("at", 0))
        if (kind == "flip" and not held and self.taken == at) or \
                (kind == "unstable" and held and self.held_cycles == at):
            return value ^ (1 << int(self.fault.get("bit", 0)))
        return value

    def _check_held(self, cycle: int, valid: int, payload):
        if self.held is None:
            return
        self.held_cycles += 1
        now = self._payload(int(payload), True) if valid == 1 and payload.is_resolvable else None
        if valid != 1 or now != self.held:
            self.on_hold_violation(cycle, self.describe(self.held), None if now is None else self.describe(now))

    def describe(self, value: int) -> dict:
        """An output payload as the report shows it."""
        return self.stream.unpack(value)

    def sample(self, cycle: int, in_reset: bool):
        v = self.valid.value
        if not v.is_resolvable:
            if not in_reset:
                self.callback(cycle, None, f"o.valid is {v}")
            self.held = None
            return
        p = self.payload.value
        self._check_held(cycle, int(v), p)
        self.held = None
        if in_reset:
            return
        if int(v) == 1:
            if self.first_valid is None:
                self.first_valid = cycle
            if not p.is_resolvable:
                if self.bp.value:
                    self.callback(cycle, None, f"payload {p}")
                return
            if not self.bp.value:
                self.held = int(p)
                return
            value = self._payload(int(p), False)
            self.taken += 1
            if self.fault.get("kind") == "drop" and self.taken - 1 == int(self.fault.get("at", 0)):
                return
            self.take(cycle, value)

    def take(self, cycle: int, value: int):
        """An output item taken: its fields to the scoreboard."""
        self.callback(cycle, self.stream.unpack(value), None)


class ResetGen:
    """Asserts the reset for ``length`` cycles when :meth:`trigger` is called."""

    def __init__(self, dut, job: Job):
        self.rst = _sig(dut, job.pm.rst)
        self.left = 0
        self.count = 0
        self.on_assert = None

    def trigger(self, length: int = 5):
        self.left = length

    def drive(self) -> bool:
        if self.left > 0:
            self.rst.value = 1
            self.left -= 1
            return True
        self.rst.value = 0
        return False


class Scoreboard:
    """In-order scoreboard: accepted items wait in ``pending``; each output must carry the next
    pending item's tag and equal its expected fields bit for bit."""

    def __init__(self, job: Job, results: Results):
        self.job = job
        self.results = results
        self.pending: deque[tuple[int, int, int]] = deque()    # (accept cycle, index, seq)
        self.expected = None
        self.inputs = None
        self.out_cycles = []      # (cycle, index, accept cycle)
        self.got = {}             # index -> {role: value}

    def accept(self, cycle, index, seq):
        self.pending.append((cycle, index, seq))

    def flush(self):
        flushed = [index for _, index, _ in self.pending]
        self.pending.clear()
        return flushed

    def hold_violation(self, cycle, held, now):
        self.results.hold_violations += 1
        self.results.mismatch("output changed while held (o.valid & ~o.ready the cycle before)",
                              None, held, now if now is not None else "o.valid low or X")

    def output(self, cycle, values, problem, kind: str = "x"):
        """An output item (its fields), or a ``problem`` with it (X/Z on the bus, or what ``kind``
        names): a mismatch of the next pending item."""
        r, job = self.results, self.job
        if problem is not None:
            if self.pending:
                _, index, seq = self.pending.popleft()
                inputs = {role: int(v[index]) for role, v in self.inputs.items()}
                self.got[index] = None
                r.compared += 1
                want = {self.job.bind_out[role]: int(v[index]) for role, v in self.expected.items()}
                r.mismatch(kind, inputs, want, problem, index)
            else:
                r.mismatch(kind, None, None, problem)
            return
        if not self.pending:
            r.stale_outputs += 1
            r.mismatch("unexpected output (nothing pending: stale after reset, or a duplicate)", None, None, values)
            return
        acc_cycle, index, seq = self.pending.popleft()
        inputs = {role: int(v[index]) for role, v in self.inputs.items()}
        if job.tag is not None and values[job.tag] != seq % job.tag_mod:
            r.tag_errors += 1
            r.mismatch("tag", inputs, {"tag": seq % job.tag_mod}, values, index)
        want = {job.bind_out[role]: int(v[index]) for role, v in self.expected.items()}
        got = {name: values[name] for name in want}
        r.compared += 1
        for name in want:
            r.count_fields(name, got[name] != want[name])
        if got != want:
            r.mismatch("value", inputs, want, got, index)
        self.got[index] = {role: values[job.bind_out[role]] for role in self.expected}
        self.out_cycles.append((cycle, index, acc_cycle))


class StreamTB:
    """Wires the components and steps them once per clock."""

    def __init__(self, dut, job: Job, results: Results, driver=None, monitor=None):
        """``driver`` / ``monitor``: the classes to use (default :class:`Driver`, :class:`Monitor`;
        the word-serial wrapper's are in :mod:`.serial`)."""
        self.dut = dut
        self.job = job
        rng = random.Random(job.seed)
        self.clk = _sig(dut, job.pm.clk)
        self.driver = (driver or Driver)(dut, job, rng)
        self.bp = BackPressure(dut, job, rng)
        self.monitor = (monitor or Monitor)(dut, job, self.bp, (job.doc.get("stream") or {}).get("fault"))
        self.reset = ResetGen(dut, job)
        self.sb = Scoreboard(job, results)
        self.driver.on_accept = self.sb.accept
        self.monitor.callback = self.sb.output
        self.monitor.on_hold_violation = self.sb.hold_violation
        self.cycle = 0
        self.was_reset = False
        self.trace = int(os.environ.get("IK5R_TB_TRACE", "0") or 0)    # log the handshakes of N cycles
        self.progress = None        # a tqdm bar of the items compared, if any

    def load(self, inputs, expected):
        self.driver.inputs = inputs
        self.sb.inputs = inputs
        self.sb.expected = expected

    async def step(self):
        await FallingEdge(self.clk)
        self.cycle += 1
        in_reset = self.reset.drive()
        if in_reset and not self.was_reset:
            self.driver.requeue(self.sb.flush())          # in flight: lost, send again
        self.was_reset = in_reset
        self.driver.drive(in_reset)
        self.bp.drive()
        await ReadOnly()
        if self.trace and self.cycle <= self.trace:
            self.dut._log.info("cycle %d rst %d i.valid %s i.ready %s o.valid %s o.ready %s", self.cycle,
                               in_reset, self.driver.valid.value, self.driver.ready.value,
                               self.monitor.valid.value, self.bp.ready.value)
        self.driver.sample(self.cycle, in_reset)
        self.monitor.sample(self.cycle, in_reset)
        if self.progress is not None and self.cycle % 1024 == 0:
            self.progress.update(len(self.sb.got) - self.progress.n)

    def idle(self) -> bool:
        return not self.driver.queue and self.driver.offering is None and not self.sb.pending

    async def run_until_idle(self, limit: int):
        start = self.cycle
        while not self.idle():
            await self.step()
            if self.cycle - start > limit:
                raise AssertionError(f"no progress: {len(self.sb.pending)} pending, {len(self.driver.queue)} queued "
                                     f"after {limit} cycles")
