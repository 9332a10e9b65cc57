"""``ik5r fk``: forward kinematics of joint vectors (CSV in, CSV out).

Input columns q1..q5 (radians, any order, extra columns ignored); output columns
px,py,pz (cm), nx,ny,nz, ox,oy,oz, ax,ay,az (the tool frame), floats at repr precision, one line
per input record. A non-finite joint value gives NaN outputs on that line.
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
    parser.set_defaults(run=run)


def run(args) -> int:
    from ik5r import csvio, reference
    from ik5r.arm import load_arm

    arm = load_arm(args.arm)
    table = csvio.read_table(args.joints, csvio.JOINT_COLUMNS)
    q = table.matrix(csvio.JOINT_COLUMNS)
    with np.errstate(invalid="ignore"):
        pose = reference.fk_pose(arm, q)
    csvio.write_table(args.output, csvio.POSE_COLUMNS, [pose[:, j] for j in range(12)])
    return 0
