"""The bulk mode of the stream testbench (:func:`.stream_tb.test_bulk`), in chunks.

Python writes the packed input vectors and the valid / ready patterns to files, pulses
``bulk_start`` and waits for ``bulk_done``; the generated wrapper's bulk engine (:mod:`.wrapper`)
streams the vectors and logs every accepted output. Expected values come from the numpy model
(checked against the scalar model on the edge set and a random sample), compared column-wise.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
from cocotb.triggers import First, RisingEdge, Timer

from . import wrapper
from .job import Job, Results

CLOCK_NS = 10


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


def compare_chunk(job: Job, results: Results, got: dict, inputs, expected, seqs, *, done_items_first: int,
                  error_sample: int | None = None) -> None:
    """Count the differences of a chunk's received outputs ``got`` (field -> array, the first
    ``m`` items) from the model's ``expected`` (role -> array) and the tags ``seqs``, every field
    and the tag, item by item; the first one is recorded with its inputs. The float error
    statistic: of every item, or of the first ``error_sample``."""
    m = len(next(iter(got.values())))
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
                         {name: int(v[i]) for name, v in got.items()}, done_items_first + i)
    e = m if error_sample is None else min(m, error_sample)
    results.errors({r: v[:e] for r, v in inputs.items()}, {r: got[job.bind_out[r]][:e] for r in job.bind_out})


class BulkRun:
    """One bulk test: chunks of vectors through the wrapper's engine, checked as they come back."""

    def __init__(self, dut, job: Job, results: Results, opts: dict):
        self.dut, self.job, self.results, self.opts = dut, job, results, opts
        self.kind = opts.get("pattern", "random")
        self.rng = np.random.default_rng([job.seed, 7])
        self.cols = wrapper.out_columns(job.pm)
        self.seq = 0                # vectors sent so far (the next tag)
        self.sim_cycles = 0
        self.sim_seconds = 0.0
        self.model_seconds = 0.0

    def write_chunk(self, inputs, seqs):
        """The chunk's packed inputs (with their tags) and fresh valid / ready patterns."""
        job, opts = self.job, self.opts
        columns = {job.bind_in[r]: v for r, v in inputs.items()}
        if job.tag:
            columns[job.tag] = seqs % job.tag_mod
        (job.work / wrapper.IN_FILE).write_text("\n".join(job.pm.i.pack_hex(columns)) + "\n")
        _write_pattern(job.work / wrapper.VPAT_FILE,
                       _pattern(self.rng, self.kind, float(opts.get("valid_duty", 0.8)), False))
        _write_pattern(job.work / wrapper.RPAT_FILE,
                       _pattern(self.rng, self.kind, float(opts.get("ready_duty", 0.75)), True))

    async def simulate(self, n: int) -> bool:
        """Stream ``n`` vectors through the engine; True if it timed out."""
        dut, pm = self.dut, self.job.pm
        ts = time.perf_counter()
        dut["bulk_count"].value = n
        dut["bulk_start"].value = 1
        cap = (n * ((pm.cycles_per_result or 1) + 1) * 8 + 100 * (pm.latency_cycles or 100) + 100000) * CLOCK_NS
        done = dut["bulk_done"]
        await First(RisingEdge(done), Timer(cap, unit="ns"))
        timed_out = not int(done.value)
        dut["bulk_start"].value = 0
        await RisingEdge(dut[pm.clk])
        self.sim_cycles += int(dut["bulk_cycles"].value)
        self.sim_seconds += time.perf_counter() - ts
        return timed_out

    def received(self, out: np.ndarray, m: int) -> dict:
        """The first ``m`` logged outputs by field, signed where the field is."""
        got = {}
        for c, name in enumerate(self.cols):
            f = self.job.pm.o.fields[name]
            raw = out[:m, c]
            got[name] = np.where(raw >= (1 << (f.width - 1)), raw - (1 << f.width), raw) if f.signed else raw
        return got

    def check(self, inputs, expected, seqs, timed_out: bool, first_index: int):
        """Compare the chunk's logged outputs with the model, every field and the tag."""
        job, results, n = self.job, self.results, len(seqs)
        out = _read_outputs(job.work / wrapper.OUT_FILE, len(self.cols))
        count = len(out)
        if timed_out or count != n:
            results.mismatch("lost", None, None, f"{count} of {n} outputs (timed out: {timed_out}, "
                                                 f"in {int(self.dut['bulk_in_count'].value)})")
        m = min(count, n)
        compare_chunk(job, results, self.received(out, m), inputs, expected, seqs, done_items_first=first_index)

    async def chunk(self, count: int, salt: int, first: bool, done_items: int) -> int:
        """One chunk (the edge set first); returns how many of ``total`` it counts for."""
        job = self.job
        tm = time.perf_counter()
        # The edge set (first chunk): all of it, or what the stream run's stride left out.
        stride, rest = int(self.opts.get("edge_stride", 1)), bool(self.opts.get("edge_rest", False))
        inputs = job.inputs(count, salt=salt, edges=first, edge_stride=stride, edge_rest=rest)
        expected = job.expected(inputs, check_scalar=256 if first else 64)
        n = len(next(iter(inputs.values())))
        seqs = np.arange(self.seq, self.seq + n, dtype=np.int64)
        self.write_chunk(inputs, seqs)
        self.model_seconds += time.perf_counter() - tm
        timed_out = await self.simulate(n)
        tm = time.perf_counter()
        self.check(inputs, expected, seqs, timed_out, done_items)
        self.model_seconds += time.perf_counter() - tm
        self.seq += n
        return n if not first else n - len(next(iter(job.edge_items(stride, rest).values())))

    async def run(self, t0: float) -> dict:
        """Every chunk; the ``bulk`` section of the result."""
        job, opts = self.job, self.opts
        total = int(opts.get("vectors", 1000))
        chunk = int(opts.get("chunk", 1 << 18))
        progress = None
        if opts.get("progress"):
            from tqdm import tqdm
            progress = tqdm(total=total, unit="vec", desc=f"{job.doc['block']} {job.doc.get('arch', '')}",
                            file=sys.stderr, dynamic_ncols=True, mininterval=0.5)
        done_items, first, salt = 0, True, 100
        while first or done_items < total:
            before = self.seq
            done_items += await self.chunk(min(chunk, total - done_items), salt, first, done_items)
            salt += 1
            first = False
            if progress:
                progress.update(self.seq - before)
            if self.results.mismatches and opts.get("stop_on_mismatch", True):
                break
        if progress:
            progress.close()
        wall = time.perf_counter() - t0
        seq, sim_seconds = self.seq, self.sim_seconds
        return {"vectors": seq, "cycles": self.sim_cycles, "pattern": self.kind,
                "sim_seconds": sim_seconds, "model_seconds": self.model_seconds,
                "wall_seconds": wall, "vectors_per_second": seq / wall if wall else None,
                "sim_vectors_per_second": seq / sim_seconds if sim_seconds else None,
                "cycles_per_second": self.sim_cycles / sim_seconds if sim_seconds else None}
