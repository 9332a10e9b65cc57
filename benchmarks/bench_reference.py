"""Throughput of the float reference IK (all four branches, FK round trip included) against
roboticstoolbox-python's numerical ``ik_LM`` on the same poses.

    python benchmarks/bench_reference.py [--count 1000000] [--lm-count 200] [--repeat 3]

Poses come from the FK of joint vectors uniform in the arm's limits (so every pose is reachable,
with n, o given). ``reference.ik`` is timed on all ``count`` poses at once, best of ``repeat``, in
wall-clock and in CPU time of this process (numpy runs on one core; CPU time leaves out other load
on the machine). ``ik_LM`` (one solution per pose, from q0 = 0) is timed on the first ``lm_count``
poses and its per-pose time extrapolated to ``count``.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from ik5r import reference
from ik5r.arm import load_arm


def _timed(fn, repeat):
    wall = cpu = math.inf
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        c1, t1 = time.process_time(), time.perf_counter()
        wall, cpu = min(wall, t1 - t0), min(cpu, c1 - c0)
    return wall, cpu


def bench(count: int = 1_000_000, lm_count: int = 200, repeat: int = 3, seed: int = 0, arm=None) -> dict:
    """Poses/s of reference.ik on ``count`` poses and the ratio against roboticstoolbox ik_LM."""
    arm = arm or load_arm()
    q = reference.random_joints(arm, count, np.random.default_rng(seed))
    p, n, o, a = reference.fk(arm, q)
    result = {}
    wall, cpu = _timed(lambda: reference.ik(arm, p, a, n, o), repeat)
    result.update(count=count, wall_s=wall, cpu_s=cpu, poses_per_s_wall=count / wall,
                  poses_per_s_cpu=count / cpu)
    res = reference.ik(arm, p, a, n, o)
    result["solved_fraction"] = float(res.valid.any(axis=1).mean())
    try:
        import roboticstoolbox as rtb
        from spatialmath import SE3
    except ImportError:
        return result
    robot = rtb.DHRobot([rtb.RevoluteDH(d=arm.d[i], a=arm.a[i], alpha=arm.alpha[i],
                                        offset=arm.theta_offset[i]) for i in range(5)])
    m = min(lm_count, count)
    frames = []
    for i in range(m):
        t = np.eye(4)
        t[:3, 0], t[:3, 1], t[:3, 2], t[:3, 3] = n[i], o[i], a[i], p[i]
        frames.append(SE3(t, check=False))
    q0 = np.zeros(5)
    successes = 0

    def run_lm():
        nonlocal successes
        successes = 0
        for frame in frames:
            successes += bool(robot.ik_LM(frame, q0=q0).success)

    lm_wall, lm_cpu = _timed(run_lm, 1)
    per_pose = lm_wall / m
    result.update(lm_count=m, lm_wall_s=lm_wall, lm_per_pose_s=per_pose,
                  lm_success_fraction=successes / m,
                  lm_extrapolated_s=per_pose * count,
                  speedup_vs_ik_lm=per_pose * count / wall)
    return result


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--count", type=int, default=1_000_000)
    parser.add_argument("--lm-count", type=int, default=200)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    r = bench(args.count, args.lm_count, args.repeat, args.seed)
    print(f"reference.ik, 4 branches + FK round trip, {r['count']:,} poses (best of {args.repeat}):")
    print(f"  wall {r['wall_s']:.3f} s = {r['poses_per_s_wall']:,.0f} poses/s;"
          f"  CPU {r['cpu_s']:.3f} s = {r['poses_per_s_cpu']:,.0f} poses/s")
    print(f"  poses with a valid branch: {r['solved_fraction']:.6f}")
    if "lm_count" in r:
        print(f"roboticstoolbox ik_LM on {r['lm_count']} of the poses: {r['lm_per_pose_s'] * 1e6:,.0f} us/pose "
              f"(success {r['lm_success_fraction']:.2f}), extrapolated {r['lm_extrapolated_s']:,.1f} s "
              f"for {r['count']:,}")
        print(f"  reference.ik is {r['speedup_vs_ik_lm']:,.0f}x faster (wall clock, all 4 branches vs 1)")
    else:
        print("roboticstoolbox not installed: no ik_LM comparison")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
