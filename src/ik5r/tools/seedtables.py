"""The seed papers' tables, reproduced with the numeric solver and set beside the published figures.

    python -m ik5r.tools.seedtables [-o build/arms] [--record]

- Toz (seed 003), Table 2's targets P1..P5 (position only, 6-DOF arm): error and time per target
  (one core, CPU time, median of repeats, one pose per call) beside Table 3's ALO errors.
- Park (seed 000), the welding move: 450 mm along y, tool direction kept (direction mode, the start
  the paper's current joints): tool-point error after each iteration beside the paper's (5th: 0.00058).
- Patil (seed 001): a grid of targets in the workspace, numeric solver against a brute-force search
  over q1..q4 on a joint grid (the paper's method, N^4), error and time per target.
- PUMA 560: random poses (joints uniform in the limits), every solution (--all): how many found.

Writes arms.json, arms.md and PNG plots to the output folder; ``--record`` also copies them to
docs/results/records/arms.json, docs/results/arms_*.png and the tables into docs/arms.md.
"""

from __future__ import annotations

import argparse
import json
import shutil
import time
from pathlib import Path

import numpy as np

from ik5r.core.chain import fk, load_chain, random_joints, shipped_arm
from ik5r.numeric import multistart
from ik5r.numeric import solver as nm

from .seedtables_report import plots, tables, update_doc

TOZ_TARGETS = np.array([[21.1736, -57.2067, 276.4353], [1.0086, -63.1067, 303.8828],
                        [-48.0754, -119.2732, 229.7840], [8.8484, -178.875, 264.7266],
                        [40.1814, 21.4357, 299.5422]])
#: Toz, Table 3: ALO objective (position error, cm) over 30 runs: minimum, maximum, mean.
TOZ_TABLE3 = {"min": [2.01e-05, 2.93e-05, 2.70e-05, 2.29e-05, 2.02e-05],
              "max": [0.310788, 0.038946, 0.009727, 0.318156, 1.363192],
              "mean": [0.015185, 0.001939, 0.000722, 0.013963, 0.05087]}
PARK_START_DEG = (-45.0, 30.0, 30.0, 90.0, -90.0)
PARK_PAPER_ERROR_5TH = 0.00058  # Fig. 8 / text: error at the 5th iteration; "< 0.01 mm after 5"


def _cpu(fn, repeat):
    times = []
    for _ in range(repeat):
        t0 = time.process_time()
        out = fn()
        times.append(time.process_time() - t0)
    return out, float(np.median(times))


def toz(repeat: int = 20) -> dict:
    chain = load_chain(shipped_arm("toz-6r"))
    rows = []
    multistart.solve(chain, nm.Targets("position", TOZ_TARGETS[:1]))  # warm-up
    for i, target in enumerate(TOZ_TARGETS):
        sol, cpu = _cpu(lambda: multistart.solve(chain, nm.Targets("position", target[None])), repeat)
        _, p = fk(chain, sol.q)
        rows.append({"target": f"P{i + 1}", "status": nm.STATUS_NAMES[sol.status[0]],
                     "error_cm": float(np.linalg.norm(p[0] - target)), "cpu_ms": cpu * 1e3,
                     "q_rad": sol.q[0].tolist(),
                     **{f"alo_{k}_cm": v[i] for k, v in TOZ_TABLE3.items()}})
    return {"targets": rows, "repeat": repeat}


def park(iterations: int = 12) -> dict:
    chain = load_chain(shipped_arm("park-5r"))
    q0 = np.radians([PARK_START_DEG])
    R0, p0 = fk(chain, q0)
    target = nm.Targets("direction", p0 + [[0.0, 45.0, 0.0]], a=R0[:, :, 2])
    trace = []
    for k in range(iterations + 1):
        q, pos, rot, _, _ = nm.levenberg_marquardt(chain, target, q0, iterations=k, polish=False)
        trace.append({"iteration": k, "error_mm": float(pos[0] * 10), "direction_rad": float(rot[0])})
    first = nm.Targets("direction", p0 + [[0.0, 1.0, 0.0]], a=R0[:, :, 2])
    step_trace = [float(nm.levenberg_marquardt(chain, first, q0, iterations=k, polish=False,
                                               damping=multistart.WARM_DAMPING)[1][0] * 10) for k in range(6)]
    # the move as a welding path: 46 points 10 mm apart, each started from the previous solution
    steps, q, worst = [], q0, 0.0
    for s in np.linspace(0.0, 45.0, 46)[1:]:
        t = nm.Targets("direction", p0 + [[0.0, s, 0.0]], a=R0[:, :, 2])
        sol = multistart.solve(chain, t, q0=q[0], starts=8, warm=True)
        q = sol.q
        worst = max(worst, float(sol.pos_err[0] * 10))
        steps.append(nm.STATUS_NAMES[sol.status[0]])
    return {"start_deg": list(PARK_START_DEG), "start_mm": (p0[0] * 10).tolist(), "trace": trace,
            "paper_error_5th": PARK_PAPER_ERROR_5TH, "path_points": len(steps), "path_first_step_error_mm": step_trace,
            "path_ok": steps.count("ok"), "path_worst_error_mm": worst}


def _brute_force(chain, target, steps):
    grid = np.linspace(-np.pi, np.pi, steps, endpoint=False)
    mesh = np.stack(np.meshgrid(grid, grid, grid, grid, indexing="ij"), axis=-1).reshape(-1, 4)
    q = np.concatenate([mesh, np.zeros((len(mesh), 1))], axis=1)
    _, p = fk(chain, q)
    err = np.linalg.norm(p - target, axis=1)
    return float(err.min())


def patil(spacing: float = 15.0, steps=(12, 24)) -> dict:
    chain = load_chain(shipped_arm("patil-5r"))
    axis = np.arange(-45.0, 45.1, spacing)
    grid = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    r = np.linalg.norm(grid, axis=1)
    targets = grid[(r <= 57.0) & (r >= 3.0)]
    sol, cpu = _cpu(lambda: multistart.solve(chain, nm.Targets("position", targets)), 3)
    _, p = fk(chain, sol.q)
    out = {"targets": len(targets), "spacing_cm": spacing, "numeric": {
        "ok": int((sol.status == nm.OK).sum()), "max_error_cm": float(np.linalg.norm(p - targets, axis=1).max()),
        "rms_error_cm": float(np.sqrt(np.mean(np.sum((p - targets) ** 2, axis=1)))),
        "ms_per_target": cpu * 1e3 / len(targets)}, "brute_force": []}
    sample = targets[:: max(1, len(targets) // 12)]
    for n in steps:
        errors, cpu = _cpu(lambda: [_brute_force(chain, t, n) for t in sample], 1)
        out["brute_force"].append({"steps_per_joint": n, "combinations": n ** 4, "targets": len(sample),
                                   "max_error_cm": max(errors), "rms_error_cm": float(np.sqrt(np.mean(np.square(errors)))),
                                   "ms_per_target": cpu * 1e3 / len(sample)})
    return out


def puma(poses: int = 1000, seed: int = 0) -> dict:
    chain = load_chain(shipped_arm("puma560"))
    q = random_joints(chain, poses, np.random.default_rng(seed))
    R, p = fk(chain, q)
    sol, cpu = _cpu(lambda: multistart.solve(chain, nm.Targets("pose", p, R), all_solutions=True), 1)
    counts = sol.counts(poses)
    ok = sol.status == nm.OK
    return {"poses": poses, "starts": multistart.DEFAULT_STARTS["all"],
            "histogram": {str(k): int(v) for k, v in enumerate(np.bincount(counts, minlength=9)) if v},
            "all_8": float(np.mean(counts == 8)), "max_pos_err_cm": float(sol.pos_err[ok].max()),
            "max_rot_err_rad": float(sol.rot_err[ok].max()), "ms_per_pose": cpu * 1e3 / poses}


def run(quick: bool = False) -> dict:
    return {"toz": toz(5 if quick else 20), "park": park(), "patil": patil(steps=(12,) if quick else (12, 24)),
            "puma560": puma(100 if quick else 1000)}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m ik5r.tools.seedtables", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("-o", "--output", default="build/arms")
    parser.add_argument("--quick", action="store_true", help="fewer repeats and poses")
    parser.add_argument("--record", action="store_true", help="copy into docs/ (records, plots, docs/arms.md)")
    args = parser.parse_args(argv)
    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    result = run(args.quick)
    (out / "arms.json").write_text(json.dumps(result, indent=2) + "\n")
    text = tables(result)
    (out / "arms.md").write_text(text + "\n")
    pngs = plots(result, out)
    print(text)
    if args.record:
        shutil.copy(out / "arms.json", Path("docs/results/records/arms.json"))
        for png in pngs:
            shutil.copy(png, Path("docs/results") / png.name)
        update_doc(Path("docs/arms.md"), text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
