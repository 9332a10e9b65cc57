"""Any serial arm from its DH table: description (TOML), forward kinematics and Jacobian, float64.

An arm TOML is the file :mod:`ik5r.core.arm` reads, grown: ``convention = "standard"`` (the default:
``Rz(theta) Tz(d) Tx(a) Rx(alpha)`` per link) or ``"modified"`` (Craig: ``Rx(alpha) Tx(a) Rz(theta)
Tz(d)``, the row of joint i holding alpha_{i-1}, a_{i-1}); 1 to 7 ``[[joint]]`` tables with
``type = "revolute" | "prismatic"`` (default revolute), ``a``, ``alpha``, ``d``, ``theta_offset``,
``scale`` (joint value = offset + scale * q: -1 for a reversed joint; the offset is
``theta_offset`` for a revolute joint, ``d`` for a prismatic one) and ``limits`` (on q, in the
file's angle unit for revolute joints, length unit for prismatic ones; revolute default -180..180
deg, prismatic required); an optional ``[tool]`` table with ``xyz`` (length unit) and ``rpy``
(angle unit; R = Rz(yaw) Ry(pitch) Rx(roll)) placing the tool frame in the last link's frame.

Internally every link is ``C_{i-1} J_i(q_i)`` with ``J_i`` a rotation about or translation along
z and ``C`` constant 4x4 transforms, so FK and the geometric Jacobian are the same code for both
conventions and both joint types.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from .errors import InputError, read_toml

MAX_JOINTS = 7
CONVENTIONS = ("standard", "modified")
JOINT_TYPES = ("revolute", "prismatic")
_LENGTH_SCALE = {"mm": 0.1, "cm": 1.0, "m": 100.0}
_ANGLE_SCALE = {"deg": math.pi / 180.0, "rad": 1.0}
_JOINT_KEYS = {"a", "alpha", "d", "theta_offset", "limits", "type", "scale"}


def _rot_x(t):
    c, s = math.cos(t), math.sin(t)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def _rot_z(t):
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def _rot_y(t):
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1.0]])


def _trans(x, y, z):
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


@dataclass(frozen=True)
class Chain:
    """A serial arm; lengths in cm, angles in radians.

    ``consts[i]`` (4x4) precedes joint i's motion about/along z; ``consts[n]`` is the tool.
    Joint i's value is ``offset[i] + scale[i] * q[i]``.
    """

    name: str
    convention: str
    prismatic: tuple[bool, ...]
    offset: tuple[float, ...]
    scale: tuple[float, ...]
    lower: np.ndarray
    upper: np.ndarray
    consts: tuple[np.ndarray, ...]
    reach: float

    @property
    def n(self) -> int:
        return len(self.prismatic)

    def wraps(self) -> np.ndarray:
        """Revolute joints whose limits span a full turn (q may be wrapped into them)."""
        return np.array([not p and hi - lo >= 2 * math.pi - 1e-12
                         for p, lo, hi in zip(self.prismatic, self.lower, self.upper)])


def _number(path, field, table, key, default=None):
    value = table.get(key, default)
    if value is None:
        raise InputError(path, "missing", field=f"{field}.{key}")
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise InputError(path, f"must be a finite number, got {value!r}", field=f"{field}.{key}")
    return float(value)


def _triple(path, field, value):
    if (not isinstance(value, list) or len(value) != 3
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)):
        raise InputError(path, f"must be 3 finite numbers, got {value!r}", field=field)
    return [float(v) for v in value]


def _choice(path, field, value, options):
    if value not in options:
        raise InputError(path, f"must be one of {list(options)}, got {value!r}", field=field)
    return value


def _limits(path, field, joint, prismatic, ls, an):
    lim = joint.get("limits")
    if lim is None:
        if prismatic:
            raise InputError(path, "a prismatic joint needs [lower, upper]", field=f"{field}.limits")
        return -math.pi, math.pi
    if (not isinstance(lim, list) or len(lim) != 2
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in lim)):
        raise InputError(path, "must be [lower, upper], finite numbers", field=f"{field}.limits")
    unit = ls if prismatic else an
    lo, hi = lim[0] * unit, lim[1] * unit
    if not lo < hi:
        raise InputError(path, "lower must be below upper", field=f"{field}.limits")
    return lo, hi


def _tool(path, doc, ls, an) -> np.ndarray:
    tool = doc.get("tool", {})
    if not isinstance(tool, dict):
        raise InputError(path, "must be a table", field="tool")
    unknown = set(tool) - {"xyz", "rpy"}
    if unknown:
        raise InputError(path, f"unknown key(s) {sorted(unknown)}", field="tool")
    x, y, z = (v * ls for v in _triple(path, "tool.xyz", tool.get("xyz", [0, 0, 0])))
    r, p, w = (v * an for v in _triple(path, "tool.rpy", tool.get("rpy", [0, 0, 0])))
    return _trans(x, y, z) @ _rot_z(w) @ _rot_y(p) @ _rot_x(r)


def parse_chain(doc: dict, path: str | Path = "<arm>") -> Chain:
    """Validate a parsed arm TOML document; every error names ``path`` and the field."""
    ls = _LENGTH_SCALE[_choice(path, "length_unit", doc.get("length_unit", "cm"), _LENGTH_SCALE)]
    an = _ANGLE_SCALE[_choice(path, "angle_unit", doc.get("angle_unit", "deg"), _ANGLE_SCALE)]
    convention = _choice(path, "convention", doc.get("convention", "standard"), CONVENTIONS)
    joints = doc.get("joint")
    if not isinstance(joints, list) or not 1 <= len(joints) <= MAX_JOINTS:
        got = len(joints) if isinstance(joints, list) else 0
        raise InputError(path, f"need 1 to {MAX_JOINTS} [[joint]] tables, got {got}", field="joint")
    prismatic, offset, scale, lower, upper = [], [], [], [], []
    pre, post = [], []
    reach = 0.0
    for i, joint in enumerate(joints):
        field = f"joint[{i + 1}]"
        if not isinstance(joint, dict):
            raise InputError(path, "must be a table", field=field)
        unknown = set(joint) - _JOINT_KEYS
        if unknown:
            raise InputError(path, f"unknown key(s) {sorted(unknown)}", field=field)
        is_p = _choice(path, f"{field}.type", joint.get("type", "revolute"), JOINT_TYPES) == "prismatic"
        a = _number(path, field, joint, "a") * ls
        alpha = _number(path, field, joint, "alpha") * an
        d = _number(path, field, joint, "d", 0.0) * ls
        theta = _number(path, field, joint, "theta_offset", 0.0) * an
        k = _number(path, field, joint, "scale", 1.0)
        if k == 0.0:
            raise InputError(path, "must not be 0", field=f"{field}.scale")
        lo, hi = _limits(path, field, joint, is_p, ls, an)
        prismatic.append(is_p)
        offset.append(d if is_p else theta)
        scale.append(k)
        lower.append(lo)
        upper.append(hi)
        fixed_z = _rot_z(theta) if is_p else _trans(0, 0, d)  # the constant part of Rz(theta) Tz(d)
        ax = _trans(a, 0, 0) @ _rot_x(alpha)
        if convention == "standard":
            pre.append(np.eye(4))
            post.append(fixed_z @ ax)
        else:
            pre.append(_rot_x(alpha) @ _trans(a, 0, 0))
            post.append(fixed_z)
        travel = max(abs(d + k * lo), abs(d + k * hi)) if is_p else abs(d)
        reach += abs(a) + travel
    tool = _tool(path, doc, ls, an)
    reach += float(np.linalg.norm(tool[:3, 3]))
    consts = [pre[0]] + [post[i] @ pre[i + 1] for i in range(len(pre) - 1)] + [post[-1] @ tool]
    consts = [np.where(np.abs(c) < 1e-15, 0.0, c) for c in consts]  # cos(90 deg) is 6e-17: make it 0
    name = doc.get("name", Path(str(path)).stem)
    if not isinstance(name, str):
        raise InputError(path, f"must be a string, got {name!r}", field="name")
    return Chain(name, convention, tuple(prismatic), tuple(offset), tuple(scale), np.array(lower),
                 np.array(upper), tuple(consts), reach)


def load_chain(path: str | Path | None = None) -> Chain:
    """Load an arm TOML as a general chain; ``None`` gives the arm of record."""
    if path is None:
        text = resources.files("ik5r").joinpath("data/seed_arm.toml").read_text()
        return parse_chain(read_toml("seed_arm.toml", text), "seed_arm.toml")
    from .arm import resolve_arm_path

    path = resolve_arm_path(path)
    return parse_chain(read_toml(path), path)


def shipped_arm(name: str) -> Path:
    """Path of a shipped arm TOML (``src/ik5r/data/arms/NAME.toml``)."""
    return Path(str(resources.files("ik5r").joinpath(f"data/arms/{name}.toml")))


def _combine(cols, weights):
    """sum_k weights[k] * cols[k], skipping zero weights (the DH constants are mostly 0 and +-1)."""
    out = None
    for col, w in zip(cols, weights):
        if w == 0.0:
            continue
        term = col if w == 1.0 else -col if w == -1.0 else w * col
        out = term if out is None else out + term
    return out if out is not None else np.zeros_like(cols[0])


def _apply(cols, p, C):
    """(R, p) <- (R, p) @ C for a constant 4x4 C; R as its three columns (N,3) each."""
    p = p if not C[:3, 3].any() else p + _combine(cols, C[:3, 3])
    return [_combine(cols, C[:3, j]) for j in range(3)], p


def frames(chain: Chain, q: np.ndarray):
    """Forward kinematics of q (N, n): tool rotation (N,3,3), tool point (N,3), joint axes
    z (N,n,3) and joint origins (N,n,3) in the base frame."""
    q = np.asarray(q, dtype=np.float64)
    count = q.shape[0]
    c0 = chain.consts[0]
    cols = [np.broadcast_to(c0[:3, j], (count, 3)) for j in range(3)]
    p = np.broadcast_to(c0[:3, 3], (count, 3))
    axes = np.empty((count, chain.n, 3))
    origins = np.empty((count, chain.n, 3))
    for i in range(chain.n):
        x, y, z = cols
        axes[:, i] = z
        origins[:, i] = p
        v = chain.offset[i] + chain.scale[i] * q[:, i]
        if chain.prismatic[i]:
            p = p + v[:, None] * z
        else:
            c, s = np.cos(v)[:, None], np.sin(v)[:, None]
            cols = [c * x + s * y, c * y - s * x, z]
        cols, p = _apply(cols, p, chain.consts[i + 1])
    return np.stack(cols, axis=2), np.asarray(p), axes, origins


def fk(chain: Chain, q: np.ndarray):
    """Tool rotation (N,3,3) and point (N,3) of joint vectors q (N, n)."""
    R, p, _, _ = frames(chain, q)
    return R, p


def fk_pose(chain: Chain, q: np.ndarray) -> np.ndarray:
    """(N, 12) px,py,pz, n, o, a: the columns ``ik5r fk`` writes."""
    R, p = fk(chain, q)
    return np.concatenate([p, R[:, :, 0], R[:, :, 1], R[:, :, 2]], axis=1)


def jacobian(chain: Chain, q: np.ndarray):
    """Tool R, p and the geometric Jacobian (N, 6, n): rows linear velocity (cm/unit), angular."""
    R, p, axes, origins = frames(chain, q)
    scale = np.asarray(chain.scale)
    d = p[:, None, :] - origins
    zx, zy, zz = axes[:, :, 0], axes[:, :, 1], axes[:, :, 2]
    dx, dy, dz = d[:, :, 0], d[:, :, 1], d[:, :, 2]
    J = np.empty((q.shape[0], 6, chain.n))
    J[:, 0], J[:, 1], J[:, 2] = zy * dz - zz * dy, zz * dx - zx * dz, zx * dy - zy * dx
    J[:, 3], J[:, 4], J[:, 5] = zx, zy, zz
    prism = np.asarray(chain.prismatic)
    if prism.any():
        J[:, :3, prism] = J[:, 3:, prism]
        J[:, 3:, prism] = 0.0
    if (scale != 1.0).any():
        J *= scale
    return R, p, J


def random_joints(chain: Chain, count: int, rng: np.random.Generator) -> np.ndarray:
    """Joint vectors drawn uniformly within the limits."""
    return rng.uniform(chain.lower, chain.upper, size=(count, chain.n))


def closed_form_arm(path: str | Path | None = None):
    """The :class:`ik5r.core.arm.Arm` of an arm file of the closed-form 5R family, else None.

    The file is validated as a general chain first (errors name FILE and field either way)."""
    from .arm import parse_arm, resolve_arm_path

    if path is None:
        return parse_arm(read_toml("seed_arm.toml", resources.files("ik5r").joinpath(
            "data/seed_arm.toml").read_text()), "seed_arm.toml")
    path = resolve_arm_path(path)
    doc = read_toml(path)
    parse_chain(doc, path)
    if doc.get("convention", "standard") != "standard" or "tool" in doc:
        return None
    try:
        return parse_arm(doc, path)
    except InputError:
        return None
