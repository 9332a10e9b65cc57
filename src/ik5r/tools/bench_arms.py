"""``make bench`` for any arm: the numeric solver against roboticstoolbox ``ik_LM`` and ikpy.

    python -m ik5r.tools.bench_arms [--poses 20000] [--rtb 1000] [--ikpy 20] [-o build/bench] [--record]

Per arm (Toz's 6R and the PUMA 560, pose mode): poses are the FK of joint vectors uniform in the
limits; ik_LM and ikpy get a first start per pose (another uniform draw), then restart as they do
by themselves (ik_LM: ``slimit`` random searches; ikpy: none); ik5r seeds itself (its start table's
entry, then uniform starts), its one-time table build timed and reported apart. A pose
counts as solved when the FK of the returned joints is within 1e-9 cm and 1e-9 rad of the target
(the floor of issue 17), measured by ik5r's FK; each tool's own success flag is reported too.
ik5r solves the whole batch at once (the C LM kernel of :mod:`ik5r.numeric.lmkernel`, numpy around it,
one core); ik_LM and ikpy are called once per pose on the first poses. Times are CPU times of this
process, one core each; ik5r and every ik_LM variant run ``--repeat`` times, interleaved so that both
see the same background load, and the median of each is kept. Writes bench_arms.json / bench_arms.md.
"""

from __future__ import annotations

import argparse
import json
import shutil
import time
from pathlib import Path

import numpy as np

from ik5r.core.chain import Chain, fk, load_chain, random_joints, shipped_arm
from ik5r.numeric import multistart, start_table
from ik5r.numeric import solver as nm

ARMS = ("toz-6r", "puma560")
TOL = 1e-9
NOTE = ("ik5r: `multistart.solve` in pose mode, one solution per pose, its own seeding (ik_LM and ikpy keep "
        "the given random first start): first the start table's entries of the pose's cell (`ik5r.numeric.start_table`: "
        "{size:,} FK samples of the arm, up to {depth} per cell, built once per arm and kept on disk, {build}; the "
        "lookup is inside the timed solve), then rounds of "
        "fresh uniform starts on the unsolved poses (up to 32 per pose), LM until 1e-11 (C kernel, one core); "
        "the row 'incl. table build' charges the whole build to this one batch. "
        "ik_LM: roboticstoolbox's C++ `ik_LM` (Chan's damping, ilimit 30, slimit 100 random restarts, joint "
        "limits) on an ETS robot of the same chain; with its default tol 1e-6 it stops short of 1e-9, so the "
        "ratio that counts is against tol 1e-20 (at least as many poses solved to 1e-9). Solved: ik5r's FK of "
        "the answer within 1e-9 cm and 1e-9 rad. CPU times, median of the interleaved runs.")


def _rtb_robot(chain: Chain):
    import roboticstoolbox as rtb
    from spatialmath import SE3

    ets = rtb.ETS()
    for i in range(chain.n):
        if chain.prismatic[i] or abs(chain.scale[i]) != 1.0:
            raise ValueError("the rtb baseline takes revolute joints of scale +-1")
        c = chain.consts[i] @ _rz(chain.offset[i])
        ets = ets * rtb.ET.SE3(SE3(c, check=False)) * rtb.ET.Rz(flip=chain.scale[i] < 0,
                                                                  qlim=[chain.lower[i], chain.upper[i]])
    ets = ets * rtb.ET.SE3(SE3(chain.consts[chain.n], check=False))
    return rtb.Robot(ets)


def _rtb_dh_robot(name: str):
    """The arm as an rtb DHRobot (standard DH only), as ik5r.tools.bench builds the 5R: ik_LM's slower
    path (the robot is turned into an ETS on every call)."""
    import roboticstoolbox as rtb

    if name != "puma560":
        return None
    rows = [(0, np.pi / 2, 0), (43.18, 0, 0), (2.03, -np.pi / 2, 15.005), (0, np.pi / 2, 43.18),
            (0, -np.pi / 2, 0), (0, 0, 0)]
    return rtb.DHRobot([rtb.RevoluteDH(a=a, alpha=alpha, d=d, qlim=[-np.pi, np.pi]) for a, alpha, d in rows])


def _rz(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def _ikpy_chain(chain: Chain):
    from ikpy.chain import Chain as IkpyChain
    from ikpy.link import OriginLink, URDFLink
    from scipy.spatial.transform import Rotation

    links = [OriginLink()]
    for i in range(chain.n + 1):
        c = chain.consts[i] @ (_rz(chain.offset[i]) if i < chain.n else np.eye(4))
        rpy = Rotation.from_matrix(c[:3, :3]).as_euler("xyz")
        kw = ({"rotation": np.array([0.0, 0.0, np.sign(chain.scale[i])]), "bounds": (chain.lower[i], chain.upper[i])}
              if i < chain.n else {"joint_type": "fixed"})
        links.append(URDFLink(name=f"j{i}", origin_translation=c[:3, 3], origin_orientation=rpy, **kw))
    return IkpyChain(links, active_links_mask=[False] + [True] * chain.n + [False])


def _errors(chain, q, R, p):
    R2, p2 = fk(chain, q)
    return nm.residuals(nm.Targets("pose", p, R), R2, p2)


def _summary(chain, q, R, p, cpu, own=None) -> dict:
    pos, rot = _errors(chain, q, R, p)
    solved = (pos <= TOL) & (rot <= TOL)
    out = {"poses": len(q), "cpu_s": cpu, "poses_per_s": len(q) / cpu, "success": float(solved.mean()),
           "max_pos_err_cm": float(np.nanmax(pos)), "max_rot_err_rad": float(np.nanmax(rot))}
    if own is not None:
        out["own_success"] = float(np.mean(own))
    return out


def _time_ik5r(chain, R, p, seed):
    t0 = time.process_time()
    sol = multistart.solve(chain, nm.Targets("pose", p, R), seed=seed)
    return time.process_time() - t0, sol.q


def _time_table(chain) -> tuple[float, float]:
    """CPU seconds of the start table's build and of its load from the disk cache (medians of 3);
    leaves it cached in the process."""
    builds, loads = [], []
    for _ in range(3):
        t0 = time.process_time()
        start_table.StartTable(chain, "pose")
        builds.append(time.process_time() - t0)
        start_table._CACHE.clear()
        start_table.table_for(chain, "pose")  # stored on disk by the first of these
        start_table._CACHE.clear()
        t0 = time.process_time()
        start_table.table_for(chain, "pose")
        loads.append(time.process_time() - t0)
    return float(np.median(builds)), float(np.median(loads))


def _time_rtb(robot, R, p, starts, tol):
    q, own = np.empty((len(p), starts.shape[1])), []
    t0 = time.process_time()
    for i in range(len(p)):
        target = np.eye(4)
        target[:3, :3], target[:3, 3] = R[i], p[i]
        res = robot.ik_LM(target, q0=starts[i], tol=tol)
        q[i] = res.q
        own.append(bool(res.success))
    return time.process_time() - t0, q, own


def bench_arm(name: str, poses: int, rtb_count: int, ikpy_count: int, seed: int = 0, repeat: int = 3) -> dict:
    """One arm: ik5r and each ik_LM variant timed ``repeat`` times, interleaved (both sides see the
    same background load), the median CPU time of each kept."""
    chain = load_chain(shipped_arm(name))
    rng = np.random.default_rng(seed)
    R, p = fk(chain, random_joints(chain, poses, rng))
    starts = random_joints(chain, poses, rng)
    multistart.solve(chain, nm.Targets("pose", p[:10], R[:10]), seed=seed)  # load the C kernel
    build, load = _time_table(chain)
    m = min(rtb_count, poses)
    variants = [(key, robot, tol) for key, robot, tol in (
        ("rtb_ik_LM", _rtb_robot(chain), 1e-6), ("rtb_ik_LM_tight", _rtb_robot(chain), 1e-20),
        ("rtb_ik_LM_dh", _rtb_dh_robot(name), 1e-20)) if robot is not None]
    times = {key: [] for key in ["ik5r"] + [v[0] for v in variants]}
    answers = {}
    for _ in range(repeat):
        cpu, answers["ik5r"] = _time_ik5r(chain, R, p, seed)
        times["ik5r"].append(cpu)
        for key, robot, tol in variants:
            cpu, q, own = _time_rtb(robot, R[:m], p[:m], starts[:m], tol)
            times[key].append(cpu)
            answers[key] = (q, own)
    cpu = float(np.median(times["ik5r"]))
    out = {"arm": name, "joints": chain.n, "repeat": repeat, "ik5r": _summary(chain, answers["ik5r"], R, p, cpu),
           "table_build_s": build, "table_load_s": load, "table_size": start_table.SIZE}
    out["ik5r_with_build"] = _summary(chain, answers["ik5r"], R, p, cpu + build)
    out["ik5r_first"] = _summary(chain, answers["ik5r"][:m], R[:m], p[:m], cpu * m / poses)
    for key, _, _ in variants:
        q, own = answers[key]
        out[key] = _summary(chain, q, R[:m], p[:m], float(np.median(times[key])), own)
        out[f"x_{key}"] = out["ik5r"]["poses_per_s"] / out[key]["poses_per_s"]
    out.update(_bench_ikpy(chain, R, p, starts, ikpy_count, out["ik5r"]["poses_per_s"]))
    return out


def _bench_ikpy(chain, R, p, starts, count, ik5r_rate) -> dict:
    ik = _ikpy_chain(chain)
    k = min(count, len(p))
    q = np.empty((k, chain.n))
    t0 = time.process_time()
    for i in range(k):
        full = ik.inverse_kinematics(p[i], R[i], orientation_mode="all",
                                     initial_position=np.concatenate([[0.0], starts[i], [0.0]]))
        q[i] = full[1:-1]
    summary = _summary(chain, q, R[:k], p[:k], time.process_time() - t0)
    return {"ikpy": summary, "x_ikpy": ik5r_rate / summary["poses_per_s"]}


def table(result: dict) -> str:
    lines = ["| arm | solver | poses | solved (<= 1e-9 cm, rad) | max position error (cm) | poses/s (CPU) | ik5r / this |",
             "| --- | --- | ---: | ---: | ---: | ---: | ---: |"]
    for r in result["arms"]:
        for key, label in (("ik5r", "ik5r numeric (batch)"), ("ik5r_with_build", "ik5r, incl. table build"),
                           ("ik5r_first", "ik5r, on the ik_LM poses"),
                           ("rtb_ik_LM", "rtb ik_LM (ETS, tol 1e-6)"), ("rtb_ik_LM_tight", "rtb ik_LM (ETS, tol 1e-20)"),
                           ("rtb_ik_LM_dh", "rtb ik_LM (DHRobot, tol 1e-20)"), ("ikpy", "ikpy")):
            if key not in r:
                continue
            s = r[key]
            ratio = f"{r['x_' + key]:.2f}" if key.startswith(("rtb", "ikpy")) else "–"
            own = f" (own flag {s['own_success']:.1%})" if "own_success" in s else ""
            lines.append(f"| {r['arm']} | {label} | {s['poses']:,} | {s['success']:.3%}{own} | "
                         f"{s['max_pos_err_cm']:.1e} | {s['poses_per_s']:,.0f} | {ratio} |")
    builds = ", ".join(f"{r['arm']} {r['table_build_s'] * 1e3:.0f} ms (load from the disk cache "
                       f"{r['table_load_s'] * 1e3:.1f} ms)" for r in result["arms"])
    return "\n".join(lines + ["", NOTE.format(build=f"build CPU time {builds}", size=start_table.SIZE,
                                                 depth=start_table.DEPTH)])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m ik5r.tools.bench_arms", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--poses", type=int, default=20000)
    parser.add_argument("--rtb", type=int, default=1000)
    parser.add_argument("--ikpy", type=int, default=20)
    parser.add_argument("--repeat", type=int, default=3, help="timed runs of each solver, interleaved (median)")
    parser.add_argument("-o", "--output", default="build/bench")
    parser.add_argument("--record", action="store_true", help="copy to docs/results/records/")
    args = parser.parse_args(argv)
    result = {"arms": [bench_arm(name, args.poses, args.rtb, args.ikpy, repeat=args.repeat) for name in ARMS]}
    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    text = table(result)
    (out / "bench_arms.json").write_text(json.dumps(result, indent=2) + "\n")
    (out / "bench_arms.md").write_text(text + "\n")
    print(text)
    if args.record:
        shutil.copy(out / "bench_arms.json", Path("docs/results/records/bench_arms.json"))
        shutil.copy(out / "bench_arms.md", Path("docs/results/records/bench_arms.md"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
