"""``ik5r solve``: inverse kinematics of poses (CSV in, CSV out) by one of three solvers.

Input columns px,py,pz,ax,ay,az and optionally nx,ny,nz,ox,oy,oz (all six or none), as ``ik5r fk``
writes them. Without n and o, q5 is --near's q5 (0 by default).

Solvers: ``float`` the float64 reference (:mod:`ik5r.core.reference`); ``fixed`` the bit-accurate
fixed-point model (``ik5r.firmware_model.vector``, the vectorised twin of ``model.py``); ``c`` the integer
C solver through ctypes (``ik5r.firmware_model.csolver``); ``rv32`` the same C cross-compiled for RV32IM
and run on a simulated VexRiscv soft CPU (``ik5r.tools.softcpu``; see ``ik5r firmware``), same CSV as c;
``numeric`` any serial arm, Levenberg-Marquardt from many starts (its columns and options:
:mod:`ik5r.tools.commands.solve_numeric`, docs/arms.md).

Branch choice: by default one line per pose, the float reference's choice: the valid branch nearest
--near when given, else the first valid one of front/elbow-up, front/elbow-down, back/elbow-up,
back/elbow-down (branch = 2 * shoulder_back + elbow_down). The fixed-point solvers (like the
hardware) take the branch as select bits (shoulder_back, elbow_down): they solve the branch the
float reference chose on the same pose. --all writes every valid branch of every pose (every
branch, with its status, when none is valid); for fixed and c it solves all four branches.

Output columns: row (0-based index of the pose in the input), branch, q1..q5 (radians), status
(``ok`` or names such as ``unreachable+singular_elbow``), residual_cm and residual_rad (the forward
kinematics of the written joints against the input: distance of the tool point, cm, and angle of
the approach, rad; NaN where the joints are), then for fixed and c q1_raw..q5_raw (integer angle
codes, Q frac.angle) and status_bits. Fixed and c quantize the inputs with the config's formats; an input
value outside the word range makes the row ``invalid+saturated``, a non-finite number ``invalid``
(q NaN; raw codes 0); the other rows are solved as usual. With --config the float solver takes the
config's tolerances (singular_sin_q3, reach_tolerance, orientation_tolerance). The file is streamed in chunks (memory
does not grow with its length). Exit status 0 once the input was read, 2 for a malformed input
file (``FILE:LINE: message``; no output file is left), 3 with ``--on-error skip`` when malformed
records were reported and left out. A negative --near needs ``--near=-0.5,...``.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from ik5r.core.fxconfig import DEFAULT_CONFIG

from .fk import add_on_error

SOLVERS = ("float", "fixed", "c", "rv32", "board", "numeric")


def _near(text: str) -> np.ndarray:
    parts = text.split(",")
    if len(parts) != 5:
        raise argparse.ArgumentTypeError(f"need 5 comma-separated joint angles (radians), got {text!r}")
    try:
        values = np.array([float(p) for p in parts])
    except ValueError:
        raise argparse.ArgumentTypeError(f"not numbers: {text!r}") from None
    if not np.isfinite(values).all():
        raise argparse.ArgumentTypeError(f"must be finite: {text!r}")
    return values


def register(subparsers) -> None:
    parser = subparsers.add_parser("solve", help="inverse kinematics: poses CSV -> joints CSV",
                                   description=__doc__,
                                   formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("poses", metavar="POSES.csv", help="CSV with columns px..az ('-': stdin)")
    parser.add_argument("-o", "--output", metavar="OUT.csv", default=None,
                        help="output CSV (default: standard output)")
    parser.add_argument("--solver", choices=SOLVERS, default=None,
                        help="float reference, fixed-point model, C solver on this host or on a "
                             "simulated RV32IM soft CPU (closed form, 5R family), or numeric (any "
                             "arm: ik5r.tools.commands.solve_numeric); default: float for the 5R family, "
                             "numeric for other arms")
    parser.add_argument("--config", metavar="CFG.toml", default=None,
                        help=f"fixed-point config TOML or shipped name (default: {DEFAULT_CONFIG})")
    parser.add_argument("--arm", metavar="ARM.toml", default=None,
                        help="arm description TOML (default: the arm of record, Hu et al.)")
    parser.add_argument("--all", action="store_true", help="write every valid branch of every pose")
    parser.add_argument("--near", type=_near, default=None, metavar="q1,q2,q3,q4,q5",
                        help="choose the branch nearest these joints (radians); also the free q1 "
                             "and the q5 of poses without n, o")
    _register_numeric(parser)
    _register_board(parser)
    add_on_error(parser)
    parser.set_defaults(run=run)


def _joint_list(text: str) -> np.ndarray:
    try:
        values = np.array([float(p) for p in text.split(",")])
    except ValueError:
        raise argparse.ArgumentTypeError(f"not numbers: {text!r}") from None
    if not np.isfinite(values).all():
        raise argparse.ArgumentTypeError(f"must be finite: {text!r}")
    return values


def _register_numeric(parser) -> None:
    from ik5r.numeric.solver import MODES

    group = parser.add_argument_group("numeric solver (--solver numeric)")
    group.add_argument("--mode", choices=MODES, default="pose",
                       help="pose (p, n, o, a), position (p) or direction (p, a; roll free); default pose")
    group.add_argument("--starts", type=int, default=None,
                       help="random starts per pose (default 32, or 128 with --all)")
    group.add_argument("--seed", type=int, default=0, help="seed of the random starts (default 0)")
    group.add_argument("--start", type=_joint_list, default=None, metavar="q1,...,qn",
                       help="first start of every pose (e.g. the current joints)")


def _register_board(parser) -> None:
    group = parser.add_argument_group("a board built by ik5r board (--solver board; docs/protocol.md)")
    group.add_argument("--port", default=None, metavar="PORT",
                       help="serial device (/dev/ttyUSB1) or pyserial URL (socket://127.0.0.1:N)")
    group.add_argument("--baud", type=int, default=3_000_000, help="baud rate of PORT (default: 3000000)")
    group.add_argument("--check", action="store_true",
                       help="compare every answer with the bit-accurate model; count differing words")


def _board_solver(k, args):
    """The board's solve_batch; with --check it also runs the model and counts differing words."""
    from ik5r.core.errors import InputError
    from ik5r.tools.boardlink import board_solver

    if not args.port:
        raise InputError("--port", "--solver board needs --port (a device or a pyserial URL)")
    on_board = board_solver(args.port, k, baud=args.baud)
    args.board_client = on_board.client
    if not args.check:
        return on_board
    from ik5r.firmware_model import vector

    args.check_counts = counts = {"poses": 0, "words": 0}

    def checked(*batch):
        q, status = on_board(*batch)
        q_model, status_model = vector.solve_batch(k, *batch)
        counts["poses"] += len(q)
        counts["words"] += int((q != q_model).sum() + (status != status_model).sum())
        return q, status
    return checked


def _fixed_solver(kind: str, k, args=None):
    """solve_batch(p_l, a_u, n_u, o_u, has_roll, shoulder_back, elbow_down, q5_default_a)."""
    if kind == "fixed":
        try:
            from ik5r.firmware_model import vector
        except ImportError as exc:
            raise RuntimeError(f"--solver fixed needs ik5r.firmware_model.vector: {exc}") from exc
        return lambda *args: vector.solve_batch(k, *args)
    if kind == "board":
        return _board_solver(k, args)
    if kind == "rv32":
        from ik5r.core.errors import InputError
        from ik5r.tools.softcpu import SoftCpu, SoftCpuError

        def on_cpu(*args):  # a missing tool, a trap or a hang: one line, exit 2
            try:
                return SoftCpu(k, isa="rv32im").solve_batch(*args)
            except SoftCpuError as exc:
                raise InputError("--solver rv32", str(exc)) from None
        return on_cpu
    try:
        from ik5r.firmware_model.csolver import CSolver
        return CSolver(k).solve_batch
    except (ImportError, OSError, RuntimeError) as exc:
        raise RuntimeError(f"--solver c: cannot load the C solver: {exc}") from exc


def _numeric_arm(args) -> bool:
    """Whether --solver is numeric; without --solver: float for the 5R family, numeric otherwise."""
    if args.solver is None:
        from ik5r.core.chain import closed_form_arm
        args.solver = "float" if closed_form_arm(args.arm) is not None else "numeric"
    return args.solver == "numeric"


def run(args) -> int:
    from ik5r.core import csvio
    from ik5r.core.arm import load_arm
    from ik5r.core.fxconfig import constants, load_config

    if _numeric_arm(args):
        from .solve_numeric import run_numeric
        return run_numeric(args)
    arm = load_arm(args.arm)
    cfg = load_config(args.config) if (args.solver != "float" or args.config is not None) else None
    solve = None
    if args.solver != "float":
        try:
            solve = _fixed_solver(args.solver, constants(cfg, arm), args)
        except RuntimeError as exc:
            print(f"ik5r solve: {exc}", file=sys.stderr)
            return 1
    names = ["row", "branch", *csvio.JOINT_COLUMNS, "status", "residual_cm", "residual_rad"]
    if solve is not None:
        names += [f"{c}_raw" for c in csvio.JOINT_COLUMNS] + ["status_bits"]
    with csvio.Writer(args.output, names) as out, \
            csvio.Reader(args.poses, csvio.POSITION_COLUMNS + csvio.APPROACH_COLUMNS,
                         groups=[csvio.ROLL_COLUMNS], on_error=args.on_error) as reader:
        for table in reader.chunks():
            out.write(_solve_chunk(table, arm, cfg, solve, args))
    if getattr(args, "check_counts", None) is not None:
        c = args.check_counts
        print(f"ik5r solve: board checked against the model: {c['poses']} poses, {c['words']} differing words",
              file=sys.stderr)
        if c["words"]:
            return 1
    return 3 if reader.skipped else 0


def _residuals(arm, q, p, a):
    """(tool point distance cm, approach angle rad) of fk(q) against the target p, a."""
    from ik5r.core import reference

    with np.errstate(invalid="ignore", over="ignore"):
        p_fk, _, _, a_fk = reference.fk(arm, q)
        dist = np.sqrt(np.sum((p_fk - p) ** 2, axis=1))
        cross = np.sqrt(np.sum(np.cross(a_fk, a) ** 2, axis=1))
        angle = np.arctan2(cross, np.sum(a_fk * a, axis=1))
    return dist, angle


def _solve_chunk(table, arm, cfg, solve, args) -> list:
    """The output columns of one chunk of poses."""
    from ik5r.core import csvio, reference
    from ik5r.core import status as st

    has_roll = "nx" in table
    p = table.matrix(csvio.POSITION_COLUMNS)
    a = table.matrix(csvio.APPROACH_COLUMNS)
    n = table.matrix(csvio.ROLL_COLUMNS[:3]) if has_roll else None
    o = table.matrix(csvio.ROLL_COLUMNS[3:]) if has_roll else None
    near = args.near
    count = len(table)
    kwargs = {} if cfg is None else {"singular_sin_q3": cfg.singular_sin_q3, "reach_tolerance": cfg.reach_tol,
                                     "orientation_tolerance": cfg.orientation_tolerance}
    res = reference.ik(arm, p, a, n, o, near=near, **kwargs)
    if solve is None:
        if args.all:
            valid = res.valid
            rows, branch = np.nonzero(valid | ~valid.any(axis=1, keepdims=True))
        else:
            rows, branch = np.arange(count), res.choose(near)
        q = res.q[rows, branch]
        status = res.status[rows, branch]
        return [table.records[rows], branch, *(q[:, j] for j in range(5)), st.describe_all(status),
                *_residuals(arm, q, p[rows], a[rows])]
    # The solvers' own status has OUT_OF_LIMITS (an arm with limits; docs/algorithm.md).
    rows, branch, q, q_raw, status = _fixed_chunk(solve, cfg, arm, res, p, a, n, o, near, args.all)
    return [table.records[rows], branch, *(q[:, j] for j in range(5)), st.describe_all(status),
            *_residuals(arm, q, p[rows], a[rows]), *(q_raw[:, j] for j in range(5)), status]


def _fixed_chunk(solve, cfg, arm, res, p, a, n, o, near, all_branches):
    """(rows, branch, q, q_raw, status) of the fixed-point solver on one chunk."""
    from ik5r.core import reference
    from ik5r.core import status as st
    from ik5r.core.fxconfig import quantize
    from ik5r.firmware_model.poses import PoseBatch

    count = len(p)
    harmless = st.SINGULAR_ELBOW | st.SINGULAR_BASE
    # The solvers' q5 input word is joint 5's DH angle (theta = offset + sense q), as the float
    # reference's near[4] becomes one: the answer then reads q5 = near[4].
    theta5 = reference.wrap(arm.theta_offset[4] + arm.sense[4] * (0.0 if near is None else near[4]))
    q5_raw, q5_sat = quantize(theta5, cfg.frac_angle, cfg)
    if bool(q5_sat):
        print("ik5r solve: --near q5 saturates the angle format", file=sys.stderr)
    poses, input_status = PoseBatch.quantise(cfg, p, a, n, o, q5=int(q5_raw))
    if all_branches:
        rows = np.repeat(np.arange(count), 4)
        branch = np.tile(np.arange(4), count)
    else:
        rows, branch = np.arange(count), res.choose(near)
    q_raw, status = poses[rows].with_branch(branch).solve(solve)
    q_raw = np.asarray(q_raw, dtype=np.int64).copy()
    status = np.asarray(status, dtype=np.int64).copy()
    bad = input_status[rows] != 0
    status[bad] = input_status[rows][bad]
    q_raw[bad] = 0
    q = q_raw * 2.0 ** -cfg.frac_angle
    q[bad] = np.nan
    if all_branches:
        valid = ((status & ~harmless) == 0).reshape(count, 4)
        keep = (valid | ~valid.any(axis=1, keepdims=True)).reshape(-1)
        rows, branch, q, q_raw, status = rows[keep], branch[keep], q[keep], q_raw[keep], status[keep]
    return rows, branch, q, q_raw, status
