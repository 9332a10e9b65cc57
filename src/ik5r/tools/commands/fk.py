"""``ik5r fk``: forward kinematics of joint vectors (CSV in, CSV out).

Input columns q1..qn, n the arm's joint count (radians; cm for prismatic joints; any order, extra
columns ignored); output columns
px,py,pz (cm), nx,ny,nz, ox,oy,oz, ax,ay,az (the tool frame), floats at repr precision, one line
per input record. A non-finite joint value gives NaN outputs on that line.

The file is streamed in chunks (memory does not grow with its length). A malformed record stops
the run with exit 2 and ``FILE:LINE: message`` (``--on-error fail``, the default); with
``--on-error skip`` it is reported so on stderr, left out, and the run exits 3. The output file is
written atomically: after a failure there is none.
"""

from __future__ import annotations

import numpy as np


def register(subparsers) -> None:
    parser = subparsers.add_parser("fk", help="forward kinematics: joints CSV -> poses CSV",
                                   description=__doc__)
    parser.add_argument("joints", metavar="JOINTS.csv", help="CSV with columns q1..q5 ('-': stdin)")
    parser.add_argument("-o", "--output", metavar="POSES.csv", default=None,
                        help="output CSV (default: standard output)")
    parser.add_argument("--arm", metavar="ARM.toml", default=None,
                        help="arm description TOML (default: the arm of record, Hu et al.)")
    add_on_error(parser)
    parser.set_defaults(run=run)


def add_on_error(parser) -> None:
    """``--on-error fail|skip``, shared with ``ik5r solve``."""
    parser.add_argument("--on-error", choices=("fail", "skip"), default="fail",
                        help="malformed record: stop with exit 2 (fail, the default), or report it as "
                             "FILE:LINE on stderr, write every good record and exit 3 (skip)")


def run(args) -> int:
    from ik5r.core import chain as general
    from ik5r.core import csvio, reference

    arm = general.closed_form_arm(args.arm)  # the 5R family keeps the reference's own FK
    model = general.load_chain(args.arm) if arm is None else None
    joints = csvio.JOINT_COLUMNS if arm is not None else tuple(f"q{i + 1}" for i in range(model.n))
    with csvio.Writer(args.output, csvio.POSE_COLUMNS) as out, \
            csvio.Reader(args.joints, joints, on_error=args.on_error) as reader:
        for table in reader.chunks():
            q = table.matrix(joints)
            with np.errstate(invalid="ignore"):
                pose = reference.fk_pose(arm, q) if arm is not None else general.fk_pose(model, q)
            out.write([pose[:, j] for j in range(12)])
    return 3 if reader.skipped else 0
