"""The field schema of a pose and of a solution, shared by every fixed-point layer.

The firmware layer's :class:`ik5r.firmware_model.poses.PoseBatch` holds these fields as word arrays, the
IK cores carry them as payload fields, the testbenches drive and check them by these names. Each
field says which fixed-point format it is in (:class:`Format`): the configuration gives each
format its fraction bits.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass


class Format(enum.Enum):
    """Fixed-point format of a field (fraction bits from the config; BIT is one bit)."""

    LENGTH = "length"       # cfg.frac_length, cm
    UNIT = "unit"           # cfg.frac_unit, components of unit vectors
    ANGLE = "angle"         # cfg.frac_angle, rad
    BIT = "bit"
    STATUS = "status"       # ik5r.core.status bits


@dataclass(frozen=True)
class Field:
    name: str
    format: Format
    doc: str


#: A pose: the solvers' input, in the argument order of every ``solve_batch``.
POSE_FIELDS = (
    Field("px", Format.LENGTH, "tool point x, cm"), Field("py", Format.LENGTH, "tool point y, cm"),
    Field("pz", Format.LENGTH, "tool point z, cm"),
    Field("ax", Format.UNIT, "approach x"), Field("ay", Format.UNIT, "approach y"),
    Field("az", Format.UNIT, "approach z"),
    Field("nx", Format.UNIT, "normal x (read if has_roll)"), Field("ny", Format.UNIT, "normal y"),
    Field("nz", Format.UNIT, "normal z (orientation check)"),
    Field("ox", Format.UNIT, "orientation x (read if has_roll)"), Field("oy", Format.UNIT, "orientation y"),
    Field("oz", Format.UNIT, "orientation z (orientation check)"),
    Field("has_roll", Format.BIT, "q5 from n, o (else q5_default)"),
    Field("shoulder_back", Format.BIT, "branch: tool point behind joint 1 (q1 + pi)"),
    Field("elbow_down", Format.BIT, "branch: q3 = -acos(c3)"),
    Field("q5_default", Format.ANGLE, "q5 without roll, rad"),
)

#: A solution: the joints and the status bits.
SOLUTION_FIELDS = tuple(Field(f"q{j}", Format.ANGLE, f"joint {j} angle, rad, in [-pi, pi]")
                        for j in range(1, 6)) + (Field("status", Format.STATUS, "ik5r.core.status bits"),)

POSE_NAMES = tuple(f.name for f in POSE_FIELDS)
SOLUTION_NAMES = tuple(f.name for f in SOLUTION_FIELDS)
