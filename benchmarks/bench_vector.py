"""Throughput of the vectorised bit-accurate model (``ik5r.firmware.vector.solve_batch``).

    python benchmarks/bench_vector.py [--config q32] [--poses 1000000] [--chunk 16384] [--repeat 3]

Prints poses/s by wall clock and by this process's CPU time (the better figure for "one core" on a
shared machine); the best of ``--repeat`` runs. ``main()`` is what ``make bench`` can call.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from ik5r import reference as ref
from ik5r.arm import load_arm
from ik5r.firmware import vector
from ik5r.fxconfig import constants, load_config, quantize


def make_poses(k, count: int, seed: int = 1):
    """Random reachable poses (all four branches, half with n/o) as solve_batch arguments."""
    arm, cfg = k.arm, k.cfg
    rng = np.random.default_rng(seed)
    p, n, o, a = ref.fk(arm, ref.random_joints(arm, count, rng))
    words = [quantize(p, cfg.frac_length, cfg)[0]] + [quantize(v, cfg.frac_unit, cfg)[0] for v in (a, n, o)]
    flags = [rng.random(count) < 0.5 for _ in range(3)]
    return (k, *words, *flags, rng.integers(-k.pi_a, k.pi_a + 1, count))


def bench(config: str = "q32", poses: int = 1_000_000, chunk: int | None = None, repeat: int = 3) -> float:
    """Best poses/s (CPU time) of ``repeat`` runs of solve_batch over ``poses`` poses; prints both."""
    k = constants(load_config(config), load_arm())
    args = make_poses(k, poses)
    if chunk:
        vector.CHUNK = chunk
    best_wall = best_cpu = 0.0
    for _ in range(repeat):
        wall, cpu = time.perf_counter(), time.process_time()
        vector.solve_batch(*args)
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        best_wall, best_cpu = max(best_wall, poses / wall), max(best_cpu, poses / cpu)
    print(f"vector.solve_batch {config}: {poses} poses, chunk {vector.CHUNK}: "
          f"{best_wall:,.0f} poses/s (wall), {best_cpu:,.0f} poses/s (CPU time)")
    return best_cpu


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="q32")
    parser.add_argument("--poses", type=int, default=1_000_000)
    parser.add_argument("--chunk", type=int, default=None)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args(argv)
    bench(args.config, args.poses, args.chunk, args.repeat)


if __name__ == "__main__":
    main()
