"""The IK core's inputs as the traced graph names them: 13 words and 3 branch flags.

Neutral ground between the tracer (:mod:`.trace`) and the two cores that build from its graph:
the pipelined core keys its state by these names, the sequenced engine maps each flag to a
condition source of its micro-ISA (``ik5r.hdl.sequenced.isa.FLAG_SOURCE``). Neither core's
internals are needed to trace. The names are the state keys of the pipelined datapath (they name
registers in the Verilog); the pose fields they come from are :data:`WORD_FIELDS` and
:data:`FLAG_FIELDS`.
"""

from __future__ import annotations

import enum

from amaranth.hdl import signed, unsigned

from ik5r.core.fxconfig import Constants
from ik5r.core.pose_fields import POSE_FIELDS, SOLUTION_FIELDS, Format

__all__ = ["BranchFlag", "INPUT_WORDS", "WORD_FIELDS", "FLAG_FIELDS", "PAYLOAD_ORDER", "core_fields",
           "tagged_fields"]


class BranchFlag(enum.Enum):
    """A one-bit input that selects a branch of the IK; the value is its state key."""
    ROLL = "roll"       # n and o are given: q5 from them, else q5 = the default word
    BACK = "back"       # shoulder back
    DOWN = "down"       # elbow down


#: The input words in the order the sequenced engine takes them (then the flags word).
INPUT_WORDS = ("px", "py", "pz", "ax", "ay", "az", "nx", "ny", "nz", "ox", "oy", "oz", "q5d")
#: The pose field (``ik5r.core.pose_fields``) each input word comes from.
WORD_FIELDS = {name: ("q5_default" if name == "q5d" else name) for name in INPUT_WORDS}
#: The pose field of each flag, in the flags word's bit order (bit 0 first).
FLAG_FIELDS = {BranchFlag.ROLL: "has_roll", BranchFlag.BACK: "shoulder_back",
               BranchFlag.DOWN: "elbow_down"}


#: The order of the pose fields in the input payload (bit layout of the Verilog port).
PAYLOAD_ORDER = ("px", "py", "pz", "ax", "ay", "az", "nx", "ny", "nz", "ox", "oy", "oz",
                 "has_roll", "q5_default", "shoulder_back", "elbow_down")


def core_fields(constants: Constants) -> tuple[dict, dict]:
    """The IK core's payload fields (name -> (shape, fraction bits, description)), in and out:
    the pose and solution schema of :mod:`ik5r.core.pose_fields`, in the formats of the config."""
    c = constants.cfg
    formats = {Format.LENGTH: (signed(c.width), c.frac_length), Format.UNIT: (signed(c.width), c.frac_unit),
               Format.ANGLE: (signed(c.width), c.frac_angle), Format.BIT: (unsigned(1), 0),
               Format.STATUS: (unsigned(constants.status_width), 0)}
    pose = {f.name: f for f in POSE_FIELDS}
    in_fields = {name: (*formats[pose[name].format], pose[name].doc) for name in PAYLOAD_ORDER}
    out_fields = {f.name: (*formats[f.format], f.doc) for f in SOLUTION_FIELDS}
    return in_fields, out_fields


def tagged_fields(constants: Constants, tag_width: int) -> tuple[dict, dict]:
    """:func:`core_fields` with the tag field (``tag_width`` bits, none for 0) last in and out:
    the payloads of the sequenced core, and of its word-level view in the testbench."""
    in_fields, out_fields = core_fields(constants)
    if tag_width:
        in_fields["tag"] = (unsigned(tag_width), 0, "carried unchanged to o.tag")
        out_fields["tag"] = (unsigned(tag_width), 0, "i.tag of the same item")
    return in_fields, out_fields
