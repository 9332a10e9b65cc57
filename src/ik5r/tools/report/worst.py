"""The worst poses of each error measure, as CSV files beside the report.

Each file lists the N poses with the largest error of one measure (fixed-point position error,
approach error, n/o error, largest joint error against float64), worst first. Its columns are the pose as
``ik5r fk`` writes it and ``ik5r solve`` reads it (px..az at repr precision), the joints q1..q5 the
pose was drawn from (``ik5r fk`` reads them back into the same pose), the branch the report solved,
the fixed-point joints and status of that branch, and the errors. So

    ik5r solve --solver fixed --config CFG --all worst_position.csv

prints, on the line of each row's ``branch``, the fixed_q1..fixed_q5 of the file (the same words,
through the same quantisation and model); --all is needed because ``ik5r solve`` alone solves the
first valid branch, and a flagged pose's branch appears there only when no branch is valid.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ik5r.core import reference as ref
from ik5r.core import status as st
from ik5r.core.fxconfig import constants, quantize

from .html import Section, esc, para, table
from .sampling import Samples

POSE = ("px", "py", "pz", "nx", "ny", "nz", "ox", "oy", "oz", "ax", "ay", "az")
MEASURES = {
    "position": ("position_err_cm", "task-space position error (cm)"),
    "approach": ("approach_err_rad", "approach-direction error (rad)"),
    "orientation": ("orientation_err_rad", "n/o error: the larger angle between solved and target n, o (rad)"),
    "joint": ("joint_err_max_rad", "largest joint error against float64 on the exact pose (rad)"),
}
COLUMNS = ("rank", *POSE, "q1", "q2", "q3", "q4", "q5", "branch",
           "fixed_q1", "fixed_q2", "fixed_q3", "fixed_q4", "fixed_q5", "fixed_status",
           "position_err_cm", "approach_err_rad", "orientation_err_rad", "joint_err_max_rad", "abs_sin_q3",
           "radius_cm")


def _fixed(samples: Samples, pose: np.ndarray, branch: np.ndarray):
    """The fixed-point joints (rad) and status of ``branch`` on ``pose`` (as the report solved them)."""
    from ik5r.firmware_model.vector import solve_batch

    cfg = samples.cfg
    k = constants(cfg, samples.arm)
    p_l, _ = quantize(pose[:, 0:3], cfg.frac_length, cfg)
    n_u, o_u, a_u = (quantize(pose[:, i:i + 3], cfg.frac_unit, cfg)[0] for i in (3, 6, 9))
    count = len(branch)
    q_raw, status = solve_batch(k, p_l, a_u, n_u, o_u, np.ones(count, dtype=bool), branch >= 2,
                                (branch & 1).astype(bool), np.zeros(count, dtype=np.int64))
    return np.asarray(q_raw, dtype=np.float64) * 2.0**-cfg.frac_angle, np.asarray(status, dtype=np.int64)


def worst_rows(samples: Samples, measure: str, count: int) -> list[dict]:
    joint = np.max(np.abs(samples.joint_err["fixed_vs_exact"]), axis=1)
    values = {"position": samples.position_err["fixed"], "approach": samples.approach_err["fixed"],
              "orientation": samples.orientation_err["fixed"], "joint": joint}[measure]
    idx = np.argsort(-values, kind="stable")[:count]
    p, n, o, a = ref.fk(samples.arm, samples.q[idx])
    pose = np.concatenate([p, n, o, a], axis=1)
    q_fx, status = _fixed(samples, pose, samples.branch[idx])
    rows = []
    for rank, i in enumerate(idx):
        row = {"rank": rank + 1, **{c: float(pose[rank, j]) for j, c in enumerate(POSE)}}
        row.update({f"q{j + 1}": float(samples.q[i, j]) for j in range(5)})
        row["branch"] = int(samples.branch[i])
        row.update({f"fixed_q{j + 1}": float(q_fx[rank, j]) for j in range(5)})
        row["fixed_status"] = st.describe(int(status[rank]))
        row.update(position_err_cm=float(samples.position_err["fixed"][i]),
                   approach_err_rad=float(samples.approach_err["fixed"][i]),
                   orientation_err_rad=float(samples.orientation_err["fixed"][i]),
                   joint_err_max_rad=float(joint[i]), abs_sin_q3=float(samples.sin_q3[i]),
                   radius_cm=float(samples.radius[i]))
        rows.append(row)
    return rows


def write_csv(path: Path, rows: list[dict]) -> None:
    with open(path, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(COLUMNS)
        for row in rows:
            writer.writerow([repr(v) if isinstance(v, float) else v for v in (row[c] for c in COLUMNS)])


def section(samples: Samples, out_dir, count: int = 20) -> Section:
    out_dir = Path(out_dir)
    files, data, shown = {}, {}, []
    for measure, (key, label) in MEASURES.items():
        rows = worst_rows(samples, measure, count)
        name = f"worst_{measure}.csv"
        write_csv(out_dir / name, rows)
        files[measure], data[measure] = name, rows
        for row in rows[:3]:
            shown.append((f"{measure} #{row['rank']}", row[key], row["position_err_cm"],
                          row["approach_err_rad"], row["orientation_err_rad"], row["joint_err_max_rad"], row["radius_cm"],
                          row["abs_sin_q3"], row["branch"], row["fixed_status"]))
    links = ", ".join(f'<a href="{esc(f)}">{esc(f)}</a> ({esc(MEASURES[m][1])})' for m, f in files.items())
    parts = [
        para(f"The {count} worst poses of each measure, worst first, as CSV: {links}. Each row holds the "
             "pose (px..az, as <code>ik5r fk</code> writes it), the joints q1..q5 it was drawn from, the "
             "branch solved, the fixed-point joints and status, and the errors. "
             f"<code>ik5r solve --solver fixed --config {esc(samples.cfg.name)} --all worst_position.csv</code> "
             "gives the same fixed_q1..fixed_q5 on each row's branch line (also for a flagged pose when "
             "no branch of it is valid; --all because <code>ik5r solve</code> alone takes the first valid "
             "branch); <code>ik5r fk</code> on the file gives the pose back from q1..q5."),
        table(("pose", "measure", "position (cm)", "approach (rad)", "n/o (rad)", "joint max (rad)", "ρ (cm)",
               "|sin q3|", "branch", "fixed status"), shown, caption="The three worst of each measure"),
    ]
    return Section("worst_poses", "Worst poses (CSV)", "\n".join(parts),
                   {"count": count, "files": files, "rows": data})
