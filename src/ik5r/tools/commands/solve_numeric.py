"""``ik5r solve --solver numeric``: any arm of :mod:`ik5r.core.chain`, by :mod:`ik5r.numeric.multistart`.

Input columns by ``--mode``: ``pose`` px,py,pz,nx..oz,ax,ay,az (as ``ik5r fk`` writes them);
``position`` px,py,pz; ``direction`` px,py,pz,ax,ay,az (tool z axis; the roll about it is free).
Bad records as for the other solvers (``--on-error``: exit 2, or skip, report and exit 3).
Output: row (0-based pose index), solution (0.. per pose), q1..qn (rad for revolute joints, cm for
prismatic ones), status (ok, not_converged, singular, unreachable, invalid), pos_err_cm,
rot_err_rad (NaN in position mode). One line per pose, or with --all one per distinct solution
(a pose with none has one line with the best start's joints and its status).
"""

from __future__ import annotations

import numpy as np

POSE_MODE_COLUMNS = {
    "pose": ("px", "py", "pz", "nx", "ny", "nz", "ox", "oy", "oz", "ax", "ay", "az"),
    "position": ("px", "py", "pz"),
    "direction": ("px", "py", "pz", "ax", "ay", "az"),
}


def read_targets(path, mode: str, on_error: str = "fail"):
    """(targets of ``mode`` from a poses CSV, their record indices, records skipped): a bad
    record is an exit 2 with FILE:LINE, or with ``on_error="skip"`` reported and left out."""
    from ik5r.core import csvio
    from ik5r.numeric.solver import Targets

    with csvio.Reader(path, POSE_MODE_COLUMNS[mode], on_error=on_error, chunk_rows=1 << 62) as reader:
        table = next(iter(reader.chunks()))
    m = table.matrix(POSE_MODE_COLUMNS[mode])
    if mode == "pose":
        targets = Targets(mode, m[:, :3], R=m[:, 3:].reshape(-1, 3, 3).swapaxes(1, 2))
    else:
        targets = Targets(mode, m[:, :3], a=m[:, 3:6] if mode == "direction" else None)
    return targets, table.records, reader.skipped


def run_numeric(args) -> int:
    from ik5r.core import csvio
    from ik5r.core.chain import load_chain
    from ik5r.core.errors import InputError
    from ik5r.numeric import multistart
    from ik5r.numeric.solver import STATUS_NAMES

    chain = load_chain(args.arm)
    joints = [f"q{i + 1}" for i in range(chain.n)]
    names = ["row", "solution", *joints, "status", "pos_err_cm", "rot_err_rad"]
    # The output is written atomically: after a bad input there is none (not even an older one).
    with csvio.Writer(args.output, names) as out:
        targets, records, skipped = read_targets(args.poses, args.mode, getattr(args, "on_error", "fail"))
        if getattr(args, "near", None) is not None:
            raise InputError("--near", "the numeric solver takes its first start from --start")
        q0 = args.start
        if q0 is not None and len(q0) != chain.n:
            raise InputError("--start", f"needs {chain.n} joint values for this arm, got {len(q0)}")
        if args.starts is not None and args.starts < 1:
            raise InputError("--starts", f"must be at least 1, got {args.starts}")
        sol = multistart.solve(chain, targets, all_solutions=args.all, starts=args.starts, q0=q0,
                               seed=args.seed, warm=q0 is not None)
        first = np.r_[True, sol.row[1:] != sol.row[:-1]] if len(sol.row) else np.zeros(0, dtype=bool)
        index = np.arange(len(sol.row)) - np.maximum.accumulate(np.where(first, np.arange(len(sol.row)), 0))
        out.write([records[sol.row], index, *(sol.q[:, j] for j in range(chain.n)),
                   [STATUS_NAMES[s] for s in sol.status], sol.pos_err, sol.rot_err])
    return 3 if skipped else 0
