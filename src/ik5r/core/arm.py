"""Standard-DH description of a serial 5R arm, loaded from TOML and validated.

The closed-form IK of ik5r needs the structure of the arm of record (Hu et al., Table 1): joint 1
vertical, joints 2-4 parallel and horizontal, joint 5 along the tool. So ``alpha`` must be
(-90, 0, 0, -90, 0) degrees, ``d2 = d3 = d4 = 0`` and ``a5 = 0``; every other parameter is free. A joint may count the other
way round (``scale = -1``: theta = theta_offset - q), as the numeric solver's chains do.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from .errors import InputError, read_toml

N_JOINTS = 5
_ALPHA_PATTERN_DEG = (-90.0, 0.0, 0.0, -90.0, 0.0)
_LENGTH_SCALE = {"mm": 0.1, "cm": 1.0, "m": 100.0}
_ANGLE_SCALE = {"deg": math.pi / 180.0, "rad": 1.0}


@dataclass(frozen=True)
class Arm:
    """A 5R arm in standard DH convention; lengths in cm, angles in radians."""

    name: str
    a: tuple[float, ...]
    alpha: tuple[float, ...]
    d: tuple[float, ...]
    theta_offset: tuple[float, ...]
    limits: tuple[tuple[float, float], ...]
    #: +1, or -1 for a joint whose positive sense is reversed: theta = theta_offset + sense * q.
    sense: tuple[int, ...] = (1,) * N_JOINTS
    #: The file it was read from (error messages name it); not part of the arm's numbers.
    source: str = field(default="<arm>", compare=False)

    @property
    def lower(self) -> np.ndarray:
        return np.array([lo for lo, _ in self.limits])

    @property
    def upper(self) -> np.ndarray:
        return np.array([hi for _, hi in self.limits])

    @property
    def max_reach(self) -> float:
        """Upper bound of |tool point - joint 2 axis| over all joint values (cm)."""
        return self.a[1] + self.a[2] + math.hypot(self.a[3], self.d[4])

    def dh_sha256(self) -> str:
        """16 hex digits of SHA-256 over the DH numbers and limits (not the name or the file): the
        arm's identity in Verilog headers, port maps, the C header and records."""
        import hashlib
        import json

        doc = {"a": self.a, "alpha": self.alpha, "d": self.d, "theta_offset": self.theta_offset,
               "limits": self.limits}
        if any(s < 0 for s in self.sense):
            # Only where a joint is reversed: the arms without one keep the hashes their records,
            # caches and Verilog headers were made under.
            doc["sense"] = self.sense
        return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()[:16]

    def fields(self) -> dict:
        """The dataclass fields as a dict, ``sense`` only where a joint is reversed: what the
        hashes of designs are taken over, so arms without one keep their earlier hashes."""
        from dataclasses import asdict

        doc = asdict(self)
        if all(s > 0 for s in self.sense):
            del doc["sense"]
        return doc

    def id_fields(self) -> dict:
        """What the ID words of a build (the board's ID frame, the peripheral's ARM_HASH) hash:
        :meth:`fields` but the name, with the file's name for its path, so that the ID of a
        build does not depend on where the clone lives (the file name stays: the ID words of the
        recorded builds of the default arm were made with it)."""
        doc = {k: v for k, v in self.fields().items() if k != "name"}
        doc["source"] = Path(str(self.source)).name
        return doc

    def theta(self, q):
        """DH joint angles of joint readings ``q`` (..., 5): theta_offset + sense * q."""
        return np.asarray(self.theta_offset) + np.asarray(self.sense) * np.asarray(q)

    @property
    def reach(self) -> float:
        """Upper bound of the tool point's distance from the joint-1 axis (cm): a1 + a2 + a3 +
        |(a4, d5)|; the scale of the tool-point error floor (error <= 5e-9 x reach)."""
        return abs(self.a[0]) + self.max_reach


def _number(path, where, table, key, default=None):
    value = table.get(key, default)
    if value is None:
        raise InputError(path, "missing", field=f"{where}.{key}")
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise InputError(path, f"must be a finite number, got {value!r}", field=f"{where}.{key}")
    return float(value)


def parse_arm(doc: dict, path: str | Path = "<arm>") -> Arm:
    """Validate a parsed arm TOML document; every error names ``path`` and the field."""
    length_unit = doc.get("length_unit", "cm")
    angle_unit = doc.get("angle_unit", "deg")
    if length_unit not in _LENGTH_SCALE:
        raise InputError(path, f"must be one of {sorted(_LENGTH_SCALE)}, got {length_unit!r}", field="length_unit")
    if angle_unit not in _ANGLE_SCALE:
        raise InputError(path, f"must be one of {sorted(_ANGLE_SCALE)}, got {angle_unit!r}", field="angle_unit")
    ls, an = _LENGTH_SCALE[length_unit], _ANGLE_SCALE[angle_unit]
    joints = doc.get("joint")
    if not isinstance(joints, list) or len(joints) != N_JOINTS:
        raise InputError(path, f"need exactly {N_JOINTS} [[joint]] tables", field="joint")
    a, alpha, d, offset, limits, sense = [], [], [], [], [], []
    for i, joint in enumerate(joints):
        where = f"joint[{i + 1}]"
        if not isinstance(joint, dict):
            raise InputError(path, "must be a table", field=where)
        unknown = set(joint) - {"a", "alpha", "d", "theta_offset", "limits", "scale"}
        if unknown:
            raise InputError(path, f"unknown key(s) {sorted(unknown)}", field=where)
        a.append(_number(path, where, joint, "a") * ls)
        alpha.append(_number(path, where, joint, "alpha") * an)
        d.append(_number(path, where, joint, "d", 0.0) * ls)
        offset.append(_number(path, where, joint, "theta_offset", 0.0) * an)
        scale = _number(path, where, joint, "scale", 1.0)
        if scale not in (1.0, -1.0):
            raise InputError(path, f"must be 1 or -1 (-1: the joint's positive sense is reversed), got {scale:g}",
                             field=f"{where}.scale")
        sense.append(int(scale))
        lim = joint.get("limits", [-180.0, 180.0] if angle_unit == "deg" else [-math.pi, math.pi])
        if (not isinstance(lim, list) or len(lim) != 2
                or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in lim)):
            raise InputError(path, "must be [lower, upper]", field=f"{where}.limits")
        lo, hi = lim[0] * an, lim[1] * an
        if not lo < hi:
            raise InputError(path, "lower must be below upper", field=f"{where}.limits")
        limits.append((lo, hi))
    for i, want in enumerate(_ALPHA_PATTERN_DEG):
        if abs(alpha[i] - math.radians(want)) > 1e-9:
            raise InputError(path, f"the closed-form IK needs alpha = {want} deg", field=f"joint[{i + 1}].alpha")
    for i in (1, 2, 3):
        if d[i] != 0.0:
            raise InputError(path, "the closed-form IK needs d = 0 here", field=f"joint[{i + 1}].d")
    if a[4] != 0.0:
        raise InputError(path, "the closed-form IK needs a = 0 here", field="joint[5].a")
    if a[1] <= 0 or a[2] <= 0:
        raise InputError(path, "links 2 and 3 must have positive length", field="joint[2].a" if a[1] <= 0 else "joint[3].a")
    return Arm(str(doc.get("name", Path(str(path)).stem)), tuple(a), tuple(alpha), tuple(d), tuple(offset),
               tuple(limits), tuple(sense), str(path))


#: The arm of record's name (``seed_arm.toml``, ``arms/hu-5r.toml``).
SEED_ARM = "hu-5r"


def arms_dir() -> Path:
    """The shipped arm files (``src/ik5r/data/arms/``)."""
    return Path(str(resources.files("ik5r").joinpath("data/arms")))


def shipped_arm_names() -> list[str]:
    return sorted(p.stem for p in arms_dir().glob("*.toml"))


def resolve_arm_path(spec: str | Path) -> Path:
    """A file, or the name of a shipped arm (``scorbot-er4u``); InputError naming the shipped ones."""
    candidate = Path(spec)
    if candidate.is_file():
        return candidate
    if not candidate.suffix and len(candidate.parts) == 1 and (arms_dir() / f"{spec}.toml").is_file():
        return arms_dir() / f"{spec}.toml"
    raise InputError(spec, f"no such arm file or shipped arm name (shipped: {', '.join(shipped_arm_names())})")


def load_arm(path: str | Path | None = None) -> Arm:
    """Load an arm TOML (a path, or a shipped arm's name); ``None`` gives the arm of record."""
    if path is None:
        return parse_arm(read_toml("seed_arm.toml", resources.files("ik5r").joinpath("data/seed_arm.toml").read_text()),
                         "seed_arm.toml")
    path = resolve_arm_path(path)
    return parse_arm(read_toml(path), path)


def is_seed_arm(arm: Arm) -> bool:
    """The arm of record's numbers (whatever its file is called): designs of it keep their old names."""
    return arm == load_arm(None)
