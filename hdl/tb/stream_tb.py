"""cocotb test module: a generic valid/ready stream testbench, configured by a job JSON.

Two tests, both comparing every output field bit for bit with the reference model and checking the
tag (a running sequence number) for order and loss:

``test_stream`` (fully cocotb-driven, in the shape of cocotb's matrix_multiplier example)
    A :class:`Driver` offers items with random idle cycles between them, a :class:`BackPressure`
    generator drives ``o.ready`` (random, with long stalls of 50-200 cycles), a :class:`Monitor`
    samples accepted outputs into an in-order :class:`Scoreboard`, and a :class:`ResetGen` asserts
    the reset in the middle of traffic: items in flight are flushed (and sent again afterwards),
    any output of a flushed item afterwards is a stale-output error. Before the random traffic it
    measures latency (one item into an empty block) and cycles per result (a full-rate burst).
    All components are stepped by one clocked loop in a fixed order per cycle (drive after the
    falling edge, sample in ReadOnly), which is deterministic on every simulator and costs two
    triggers per clock.

``test_bulk`` (fast)
    Drives the generated wrapper's bulk engine (see :mod:`.wrapper`): Python writes the packed
    input vectors and the valid / ready patterns to files, pulses ``bulk_start`` and waits for
    ``bulk_done``; the HDL streams the vectors and logs every accepted output. Expected values come
    from the numpy model (checked against the scalar model on the edge set and a random sample).

The job JSON (path in ``IK5R_TB_JOB``) names the port map, block, config, seed, what to run, and
where to write the result JSON.
"""

from __future__ import annotations

import json
import os
import random
import sys
import time
from collections import deque
from pathlib import Path

import cocotb
import numpy as np
from cocotb.clock import Clock
from cocotb.triggers import ClockCycles, FallingEdge, First, ReadOnly, RisingEdge, Timer

from ik5r.fxconfig import constants, load_config
from ik5r.hdl.tb import wrapper
from ik5r.hdl.tb.blocks import get_block
from ik5r.hdl.tb.portmap import load_portmap

CLOCK_NS = 10


# ---- job / reference --------------------------------------------------------------------------

class Job:
    def __init__(self, path: str | None = None):
        path = path or os.environ["IK5R_TB_JOB"]
        self.doc = json.loads(Path(path).read_text())
        d = self.doc
        self.pm = load_portmap(d["portmap"])
        self.spec = get_block(d["block"])
        self.k = constants(load_config(d.get("config")))
        self.seed = int(d.get("seed", 1))
        self.work = Path(d["work_dir"])
        self.bind_in, self.bind_out = self.spec.bind(self.pm)
        self.tag = self.pm.tag_field
        self.tag_mod = 1 << self.pm.o.fields[self.tag].width if self.tag else None

    def inputs(self, count: int, salt: int, edges: bool = True) -> dict[str, np.ndarray]:
        """Edge set (if asked) then ``count`` random items, by role, clipped to nothing: the
        generators stay inside each field's range."""
        rng = np.random.default_rng([self.seed, salt])
        parts = []
        if edges:
            parts.append(self.spec.edge_inputs(self.pm, self.k))
        if count:
            parts.append(self.spec.random_inputs(rng, count, self.pm, self.k))
        out = {r: np.concatenate([p[r] for p in parts]).astype(np.int64) for r in self.spec.inputs}
        for role, name in self.bind_in.items():
            f = self.pm.i.fields[name]
            bad = (out[role] < f.lo) | (out[role] > f.hi)
            if bad.any():
                raise ValueError(f"stimulus for {role} outside field {name} range: {out[role][bad][:4]}")
        return out

    def expected(self, inputs, check_scalar: int = 256) -> dict[str, np.ndarray]:
        """Vector model over all items; the scalar model (the spec) on the first ``check_scalar``
        items and a random sample of as many more; any disagreement is a model error (raises)."""
        exp = {r: np.asarray(v, dtype=np.int64) for r, v in self.spec.model_vec(inputs, self.pm, self.k).items()}
        n = len(next(iter(inputs.values())))
        idx = list(range(min(n, check_scalar)))
        if n > check_scalar:
            idx += sorted(np.random.default_rng(self.seed).choice(np.arange(check_scalar, n),
                                                                  min(check_scalar, n - check_scalar), replace=False))
        for i in idx:
            want = self.spec.model_scalar({r: int(v[i]) for r, v in inputs.items()}, self.pm, self.k)
            got = {r: int(exp[r][i]) for r in want}
            if got != want:
                raise AssertionError(f"vector model != scalar model at {i}: inputs "
                                     f"{ {r: int(v[i]) for r, v in inputs.items()} } scalar {want} vector {got}")
        return exp


class Results:
    """Accumulates compared items, mismatches and timing; written to the job's result JSON."""

    def __init__(self, job: Job):
        self.job = job
        self.compared = 0
        self.mismatches = 0
        self.first_mismatch = None
        self.field_mismatches = {}      # output field -> items where it differs from the model
        self.tag_errors = 0
        self.stale_outputs = 0
        self.hold_violations = 0
        self.err_max = 0.0
        self.err_sq = 0.0
        self.err_n = 0
        self.sections = {}

    def mismatch(self, kind, inputs, expected, got, index=None):
        self.mismatches += 1
        if self.first_mismatch is None:
            self.first_mismatch = {"kind": kind, "index": index, "inputs": inputs, "expected": expected, "got": got}

    def count_fields(self, name: str, count: int) -> None:
        self.field_mismatches[name] = self.field_mismatches.get(name, 0) + int(count)

    def errors(self, inputs, got):
        err = np.asarray(self.job.spec.float_error(inputs, got, self.job.pm, self.job.k), dtype=np.float64)
        if err.size:
            self.err_max = max(self.err_max, float(err.max()))
            self.err_sq += float(np.sum(err * err))
            self.err_n += int(err.size)

    def write(self, path, extra=None):
        doc = {"compared": self.compared, "mismatches": self.mismatches, "first_mismatch": self.first_mismatch,
               "field_mismatches": {name: self.field_mismatches.get(name, 0) for name in self.job.bind_out.values()},
               "tag_errors": self.tag_errors, "stale_outputs": self.stale_outputs,
               "hold_violations": self.hold_violations,
               "max_error_lsb": self.err_max if self.err_n else None,
               "rms_error_lsb": (self.err_sq / self.err_n) ** 0.5 if self.err_n else None,
               "error_items": self.err_n, **self.sections, **(extra or {})}
        Path(path).write_text(json.dumps(doc, indent=1, default=_jsonable))
        return doc


def _jsonable(v):
    if isinstance(v, (np.integer,)):
        return int(v)
    if isinstance(v, (np.floating,)):
        return float(v)
    if isinstance(v, np.ndarray):
        return v.tolist()
    raise TypeError(type(v))


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

    def word(self, index: int, seq: int) -> int:
        values = {self.job.bind_in[r]: int(v[index]) for r, v in self.inputs.items()}
        if self.job.tag:
            values[self.job.tag] = seq % self.job.tag_mod
        return self.stream.pack(values)

    def drive(self, in_reset: bool):
        if in_reset:
            self.valid.value = 0
            return
        if self.offering is None and self.queue:
            if self._idle > 0:
                self._idle -= 1
            elif self.idle_prob and self.rng.random() < self.idle_prob:
                self._idle = self.rng.randint(0, self.idle_max)
            else:
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
    flips bit 0 of the n-th taken payload, ``"drop"`` swallows the n-th taken item (a lost tag),
    ``"unstable"`` flips bit 0 of the payload in the n-th held cycle."""

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
            return value ^ 1
        return value

    def _check_held(self, cycle: int, valid: int, payload):
        if self.held is None:
            return
        self.held_cycles += 1
        now = self._payload(int(payload), True) if valid == 1 and payload.is_resolvable else None
        if valid != 1 or now != self.held:
            self.on_hold_violation(cycle, self.stream.unpack(self.held),
                                   None if now is None else self.stream.unpack(now))

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

    def output(self, cycle, values, problem):
        r, job = self.results, self.job
        if problem is not None:       # X/Z on the bus: a mismatch of the next pending item
            if self.pending:
                _, index, seq = self.pending.popleft()
                inputs = {role: int(v[index]) for role, v in self.inputs.items()}
                self.got[index] = None
                r.compared += 1
                want = {self.job.bind_out[role]: int(v[index]) for role, v in self.expected.items()}
                r.mismatch("x", inputs, want, problem, index)
            else:
                r.mismatch("x", None, None, problem)
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

    def __init__(self, dut, job: Job, results: Results):
        self.dut = dut
        self.job = job
        rng = random.Random(job.seed)
        self.clk = _sig(dut, job.pm.clk)
        self.driver = Driver(dut, job, rng)
        self.bp = BackPressure(dut, job, rng)
        self.monitor = Monitor(dut, job, self.bp, (job.doc.get("stream") or {}).get("fault"))
        self.reset = ResetGen(dut, job)
        self.sb = Scoreboard(job, results)
        self.driver.on_accept = self.sb.accept
        self.monitor.callback = self.sb.output
        self.monitor.on_hold_violation = self.sb.hold_violation
        self.cycle = 0
        self.was_reset = False
        self.trace = int(os.environ.get("IK5R_TB_TRACE", "0") or 0)    # log the handshakes of N cycles

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

    def idle(self) -> bool:
        return not self.driver.queue and self.driver.offering is None and not self.sb.pending

    async def run_until_idle(self, limit: int):
        start = self.cycle
        while not self.idle():
            await self.step()
            if self.cycle - start > limit:
                raise AssertionError(f"no progress: {len(self.sb.pending)} pending, {len(self.driver.queue)} queued "
                                     f"after {limit} cycles")


def _limit(job: Job, items: int) -> int:
    lat = job.pm.latency_cycles or 100
    cpr = job.pm.cycles_per_result or 1
    return 20 * (lat + 50) + items * (cpr + 1) * 40 + 10000


async def _start(dut, job: Job):
    Clock(_sig(dut, job.pm.clk), CLOCK_NS, unit="ns").start()
    for name in ("bulk_start", "bulk_count"):
        try:
            _sig(dut, name).value = 0
        except (AttributeError, KeyError):
            pass
    pm = job.pm
    _sig(dut, pm.i.valid).value = 0
    _sig(dut, pm.o.ready).value = 0
    _sig(dut, pm.i.payload).value = 0
    _sig(dut, pm.rst).value = 1
    await ClockCycles(_sig(dut, pm.clk), 3)
    await FallingEdge(_sig(dut, pm.clk))
    _sig(dut, pm.rst).value = 0


@cocotb.test()
async def test_stream(dut):
    job = Job()
    opts = job.doc.get("stream")
    if not opts:
        return
    results = Results(job)
    t0 = time.perf_counter()
    await _start(dut, job)
    tb = StreamTB(dut, job, results)
    inputs = job.inputs(int(opts.get("vectors", 1000)), salt=1)
    expected = job.expected(inputs)
    tb.load(inputs, expected)
    n = len(next(iter(inputs.values())))
    order = list(range(n))
    lat = job.pm.latency_cycles or 0
    try:
        await _stream_phases(dut, job, tb, results, opts, inputs, expected, n, order, lat, t0)
    finally:
        if "stream" not in results.sections:       # failed part-way: still report what was seen
            results.sections["stream"] = {"vectors": n, "cycles": tb.cycle, "aborted": True}
            results.write(job.work / "result_stream.json")


async def _stream_phases(dut, job, tb, results, opts, inputs, expected, n, order, lat, t0):

    # 1. latency: one item into an empty block, always ready.
    tb.driver.queue.extend(order[:1])
    await tb.run_until_idle(_limit(job, 1))
    latency = tb.sb.out_cycles[-1][0] - tb.sb.out_cycles[-1][2] if tb.sb.out_cycles else None
    # 2. cycles per result: a full-rate burst.
    # At most half the items, so the random phase (with its mid-traffic reset) keeps the rest.
    burst = min((n - 1) // 2, max(32, 3 * lat + 16))
    tb.driver.queue.extend(order[1:1 + burst])
    await tb.run_until_idle(_limit(job, burst))
    outs = [c for c, _, _ in tb.sb.out_cycles[-burst:]] if len(tb.sb.out_cycles) > burst else []
    cpr = (outs[-1] - outs[0]) / (len(outs) - 1) if len(outs) > 1 else None
    # 3. random idles and back-pressure with long stalls, reset in the middle of traffic.
    rest = order[1 + burst:]
    tb.driver.idle_prob, tb.driver.idle_max = float(opts.get("idle_prob", 0.3)), int(opts.get("idle_max", 8))
    tb.bp.mode = "random"
    half = len(rest) // 2
    tb.driver.queue.extend(rest)
    resets = 0
    held_at_reset = False
    if opts.get("reset", True) and half:
        # Reset once traffic is flowing, the block holds items in flight and its output is held
        # (o.valid & ~o.ready): stability under a stall and the reset's release checked together.
        limit_c = tb.cycle + _limit(job, half)
        while len(tb.driver.accepted) < 1 + burst + half or not tb.sb.pending or tb.monitor.held is None:
            await tb.step()
            if tb.cycle > limit_c:
                raise AssertionError("traffic did not reach the mid-point")
        in_flight = len(tb.sb.pending)
        tb.reset.trigger(int(opts.get("reset_cycles", 4)))
        resets = 1
        held_at_reset = True
        dut._log.info("reset asserted at cycle %d with %d items in flight", tb.cycle, in_flight)
    await tb.run_until_idle(_limit(job, len(rest)))
    # Nothing may come out after the last item: a few more cycles, ready high.
    tb.bp.mode = "always"
    for _ in range(max(20, 2 * lat)):
        await tb.step()
    missing = sorted(set(order) - set(tb.sb.got))
    if missing:
        results.mismatch("lost", None, None, f"{len(missing)} items never came out, first {missing[:5]}")
    idx = np.array(sorted(i for i, v in tb.sb.got.items() if v is not None), dtype=np.int64)
    if idx.size:
        got = {role: np.array([tb.sb.got[i][role] for i in idx], dtype=np.int64) for role in expected}
        results.errors({r: v[idx] for r, v in inputs.items()}, got)
    wall = time.perf_counter() - t0
    results.sections["stream"] = {"vectors": n, "cycles": tb.cycle, "resets": resets,
                                  "reset_while_held": held_at_reset, "held_cycles": tb.monitor.held_cycles,
                                  "latency_cycles": latency, "cycles_per_result": cpr,
                                  "wall_seconds": wall}
    doc = results.write(job.work / "result_stream.json")
    dut._log.info("stream: %d compared, %d mismatches, latency %s, cycles/result %s, %.0f cycles/s",
                  results.compared, results.mismatches, latency, cpr, tb.cycle / wall)
    assert results.mismatches == 0, f"first mismatch: {doc['first_mismatch']}"
    assert results.compared == n


# ---- bulk mode -----------------------------------------------------------------------------------

def _pattern(rng: np.random.Generator, kind: str, duty: float, stalls: bool) -> np.ndarray:
    n = 1 << wrapper.PATTERN_BITS
    if kind == "full":
        return np.ones(n, dtype=np.uint8)
    pat = (rng.random(n) < duty).astype(np.uint8)
    if stalls:
        for start in rng.integers(0, n, max(1, n // 2000)):
            pat[start:start + int(rng.integers(50, 200))] = 0
    return pat


def _write_pattern(path: Path, pat: np.ndarray):
    path.write_text("\n".join("1" if b else "0" for b in pat.tolist()) + "\n")


def _read_outputs(path: Path, cols: int) -> np.ndarray:
    text = path.read_text()
    try:
        arr = np.array(text.split(), dtype=np.int64)
    except ValueError:
        rows = []
        for line in text.splitlines():
            rows.append([int(t) if t.lstrip("-").isdigit() else np.iinfo(np.int64).min for t in line.split()])
        arr = np.array(rows, dtype=np.int64).reshape(-1)
    return arr.reshape(-1, cols)


@cocotb.test()
async def test_bulk(dut):
    job = Job()
    opts = job.doc.get("bulk")
    if not opts:
        return
    results = Results(job)
    t0 = time.perf_counter()
    await _start(dut, job)
    clk = _sig(dut, job.pm.clk)
    pm = job.pm
    total = int(opts.get("vectors", 1000))
    chunk = int(opts.get("chunk", 1 << 18))
    kind = opts.get("pattern", "random")
    rng = np.random.default_rng([job.seed, 7])
    cols = wrapper.out_columns(pm)
    progress = None
    if opts.get("progress"):
        from tqdm import tqdm
        progress = tqdm(total=total, unit="vec", desc=f"{job.doc['block']} {job.doc.get('arch', '')}",
                        file=sys.stderr, dynamic_ncols=True, mininterval=0.5)
    seq = 0
    done_items = 0
    sim_cycles = 0
    sim_seconds = 0.0
    model_seconds = 0.0
    first = True
    salt = 100
    while first or done_items < total:
        count = min(chunk, total - done_items)
        tm = time.perf_counter()
        inputs = job.inputs(count, salt=salt, edges=first)
        salt += 1
        expected = job.expected(inputs, check_scalar=256 if first else 64)
        n = len(next(iter(inputs.values())))
        seqs = np.arange(seq, seq + n, dtype=np.int64)
        columns = {job.bind_in[r]: v for r, v in inputs.items()}
        if job.tag:
            columns[job.tag] = seqs % job.tag_mod
        (job.work / wrapper.IN_FILE).write_text("\n".join(pm.i.pack_hex(columns)) + "\n")
        _write_pattern(job.work / wrapper.VPAT_FILE, _pattern(rng, kind, float(opts.get("valid_duty", 0.8)), False))
        _write_pattern(job.work / wrapper.RPAT_FILE, _pattern(rng, kind, float(opts.get("ready_duty", 0.75)), True))
        model_seconds += time.perf_counter() - tm
        ts = time.perf_counter()
        _sig(dut, "bulk_count").value = n
        _sig(dut, "bulk_start").value = 1
        cap = (n * ((pm.cycles_per_result or 1) + 1) * 8 + 100 * (pm.latency_cycles or 100) + 100000) * CLOCK_NS
        done = _sig(dut, "bulk_done")
        await First(RisingEdge(done), Timer(cap, unit="ns"))
        timed_out = not int(done.value)
        _sig(dut, "bulk_start").value = 0
        await RisingEdge(clk)
        sim_cycles += int(_sig(dut, "bulk_cycles").value)
        sim_seconds += time.perf_counter() - ts
        tm = time.perf_counter()
        out = _read_outputs(job.work / wrapper.OUT_FILE, len(cols))
        if timed_out or len(out) != n:
            results.mismatch("lost", None, None,
                             f"{len(out)} of {n} outputs (timed out: {timed_out}, in {int(_sig(dut, 'bulk_in_count').value)})")
        m = min(len(out), n)
        got = {}
        for c, name in enumerate(cols):
            f = pm.o.fields[name]
            raw = out[:m, c]
            got[name] = np.where(raw >= (1 << (f.width - 1)), raw - (1 << f.width), raw) if f.signed else raw
        bad = np.zeros(m, dtype=bool)
        if job.tag:
            tag_bad = got[job.tag] != seqs[:m] % job.tag_mod
            results.tag_errors += int(tag_bad.sum())
            bad |= tag_bad
        for role, name in job.bind_out.items():
            field_bad = got[name] != expected[role][:m]
            results.count_fields(name, field_bad.sum())
            bad |= field_bad
        results.compared += m
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            results.mismatches += int(bad.sum()) - 1
            results.mismatch("value" if not job.tag or got[job.tag][i] == seqs[i] % job.tag_mod else "tag",
                             {r: int(v[i]) for r, v in inputs.items()},
                             {job.bind_out[r]: int(v[i]) for r, v in expected.items()} | (
                                 {job.tag: int(seqs[i] % job.tag_mod)} if job.tag else {}),
                             {name: int(got[name][i]) for name in cols}, done_items + i)
        results.errors({r: v[:m] for r, v in inputs.items()}, {r: got[job.bind_out[r]] for r in job.bind_out})
        model_seconds += time.perf_counter() - tm
        seq += n
        done_items += n if not first else n - len(job.spec.edge_inputs(pm, job.k)[next(iter(job.spec.inputs))])
        first = False
        if progress:
            progress.update(n)
        if results.mismatches and opts.get("stop_on_mismatch", True):
            break
    if progress:
        progress.close()
    wall = time.perf_counter() - t0
    results.sections["bulk"] = {"vectors": seq, "cycles": sim_cycles, "pattern": kind,
                                "sim_seconds": sim_seconds, "model_seconds": model_seconds,
                                "wall_seconds": wall, "vectors_per_second": seq / wall if wall else None,
                                "sim_vectors_per_second": seq / sim_seconds if sim_seconds else None,
                                "cycles_per_second": sim_cycles / sim_seconds if sim_seconds else None}
    doc = results.write(job.work / "result_bulk.json")
    dut._log.info("bulk: %d compared, %d mismatches, %.0f vectors/s (sim only %.0f), %d cycles",
                  results.compared, results.mismatches, seq / wall, seq / max(sim_seconds, 1e-9), sim_cycles)
    assert results.mismatches == 0, f"first mismatch: {doc['first_mismatch']}"
