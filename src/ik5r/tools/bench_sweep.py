"""make bench (part 2): the sweep and report floors of issue 18, timed.

* ik5r sweep --no-synth over widths 12..32 x internal guard bits 0..8 (189 points, 100,000 poses
  each) on a LocalCluster of 2 processes, from an empty cache: floor 300 s;
* ik5r report --configs q18,q24,q32,q32w --vectors 100000: floor 60 s.

Writes build/bench/sweep_bench.json and prints one line per floor (wall seconds, CPU seconds).

    python -m ik5r.tools.bench_sweep [--jobs 2] [-o build/bench]
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import tempfile
import time
from pathlib import Path


def _cpu_seconds() -> float:
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def sweep_floor(jobs: int, work: Path) -> dict:
    from .sweep import run_sweep
    from .sweep_record import SweepOptions

    start = time.perf_counter()
    options = SweepOptions(widths=range(12, 33), blocks=(), archs=(), synth=False, guard_bits=range(0, 9))
    result = run_sweep(options, out_dir=work / "sweep", jobs=jobs, progress=False, log=lambda m: None)
    wall = time.perf_counter() - start
    points = result.points
    return {"command": f"ik5r sweep --no-synth --widths 12..32 --guard-bits 0..8 --jobs {jobs}",
            "points": len(points), "failures": len(result.failures), "wall_s": round(wall, 1),
            "worker_cpu_s": round(sum(p.get("error_cpu_seconds") or 0 for p in points), 1),
            "floor_s": 300, "met": wall <= 300 and len(points) >= 100}


def compare_floor(work: Path) -> dict:
    from .report.compare import build_comparison

    start, cpu = time.perf_counter(), _cpu_seconds()
    build_comparison(work / "compare", ["q18", "q24", "q32", "q32w"], vectors=100_000, log=lambda m: None)
    wall = time.perf_counter() - start
    return {"command": "ik5r report --configs q18,q24,q32,q32w --vectors 100000", "wall_s": round(wall, 1),
            "cpu_s": round(_cpu_seconds() - cpu, 1), "floor_s": 60, "met": wall <= 60}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m ik5r.tools.bench_sweep", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--jobs", type=int, default=2, help="LocalCluster processes (default: 2)")
    parser.add_argument("-o", "--output", default="build/bench")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="ik5r-bench-sweep-") as tmp:
        results = [compare_floor(Path(tmp)), sweep_floor(args.jobs, Path(tmp))]
    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    (out / "sweep_bench.json").write_text(json.dumps(results, indent=2) + "\n")
    for r in results:
        extra = f", {r['points']} points, worker CPU {r['worker_cpu_s']} s" if "points" in r else \
            f", CPU {r['cpu_s']} s"
        print(f"{'met' if r['met'] else 'MISSED'}: {r['command']}: {r['wall_s']} s wall "
              f"(floor {r['floor_s']} s{extra})")
    return 0 if all(r["met"] for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
