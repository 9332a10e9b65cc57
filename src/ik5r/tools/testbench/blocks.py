"""What the testbench knows about each block: its reference model, stimulus and float reference.

A :class:`BlockSpec` names the block's model inputs and outputs as *roles*; each role is matched to
a payload field of the port map by name (with aliases), so the generator may call a field ``x`` or
``x_u``. Everything else (widths, signedness, tag) comes from the port map.

To add a block (e.g. the IK core of issue 4): write a BlockSpec with ``model_vec`` (numpy, for the
bulk runs; the IK core's is the C solver, bit-exact with the numpy model), ``model_scalar`` (``ik5r.firmware_model.model``, the specification), ``random_inputs``,
``edge_inputs`` and ``float_error``, and put it in :data:`BLOCKS`. The testbench, ``ik5r sim`` and
the tests pick it up by name.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from typing import Callable

import numpy as np

from ik5r.core import status as st
from ik5r.core.fxconfig import Constants
from ik5r.core.modes import Block
from ik5r.core.pose_fields import SOLUTION_NAMES
from ik5r.firmware_model import csolver
from ik5r.firmware_model import model as M
from ik5r.firmware_model import vector as V
from ik5r.firmware_model import vectors
from ik5r.firmware_model.poses import FIELDS, PoseBatch

from .portmap import PortMap

Arrays = dict[str, np.ndarray]


@dataclass
class BlockSpec:
    name: str
    inputs: dict[str, tuple[str, ...]]          # role -> accepted field names (first wins)
    outputs: dict[str, tuple[str, ...]]
    #: (inputs by role, port map, constants) -> outputs by role (int64 arrays / bool arrays)
    model_vec: Callable[[Arrays, PortMap, Constants], Arrays]
    #: one item: (inputs by role, port map, constants) -> outputs by role (ints)
    model_scalar: Callable[[dict[str, int], PortMap, Constants], dict[str, int]]
    random_inputs: Callable[[np.random.Generator, int, PortMap, Constants], Arrays]
    edge_inputs: Callable[[PortMap, Constants], Arrays]
    #: (inputs, outputs as received, port map, constants) -> error in output LSB per item (float)
    float_error: Callable[[Arrays, Arrays, PortMap, Constants], np.ndarray]

    def bind(self, pm: PortMap) -> tuple[dict[str, str], dict[str, str]]:
        """Role -> payload field name, for inputs and outputs; raises on a field it cannot match."""
        def match(roles, fields, side):
            out = {}
            for role, names in roles.items():
                hit = next((n for n in names if n in fields), None)
                if hit is None:
                    raise ValueError(f"{self.name}: no {side} field for {role!r} (tried {names}) in {sorted(fields)}")
                out[role] = hit
            return out
        bi = match(self.inputs, pm.i.fields, "input")
        bo = match(self.outputs, pm.o.fields, "output")
        tag = pm.tag_field
        extra_in = set(pm.i.fields) - set(bi.values()) - {tag}
        extra_out = set(pm.o.fields) - set(bo.values()) - {tag}
        if extra_in:
            raise ValueError(f"{self.name}: input fields {sorted(extra_in)} have no role in the testbench")
        if extra_out:
            raise ValueError(f"{self.name}: output fields {sorted(extra_out)} are not checked by the testbench")
        return bi, bo


# ---- stimulus helpers -------------------------------------------------------------------------

def _field_of(pm: PortMap, spec: BlockSpec, role: str):
    bi, _ = spec.bind(pm)
    return pm.i.fields[bi[role]]


def _words(rng, n, lo, hi, k: Constants):
    """Half uniform over [lo, hi], half with a random number of top bits shifted away (small
    values, to exercise normalisation and small-magnitude paths)."""
    a = rng.integers(lo, hi, n, endpoint=True)
    small = rng.random(n) < 0.5
    shift = rng.integers(0, max(1, k.cfg.width - 1), n)
    return np.where(small, a >> shift, a).astype(np.int64)


def _frac(pm: PortMap, field_name: str, side: str, default: int) -> int:
    f = (pm.i if side == "i" else pm.o).fields[field_name]
    return default if f.frac is None else f.frac


# ---- atan2 -----------------------------------------------------------------------------------

def _atan2_vec(x, pm, k):
    a, m, z = V.cordic_atan2(x["y"], x["x"], k)
    return {"angle": a, "magnitude": m, "zero": np.asarray(z).astype(np.int64)}


def _atan2_scalar(x, pm, k):
    a, m, z = M.cordic_atan2(x["y"], x["x"], k)
    return {"angle": a, "magnitude": m, "zero": int(z)}


def _atan2_random(rng, n, pm, k):
    return {"y": _words(rng, n, k.word_min, k.word_max, k), "x": _words(rng, n, k.word_min, k.word_max, k)}


def _atan2_edges(pm, k):
    lo, hi = k.word_min, k.word_max
    vals = [0, 1, -1, 2, -2, hi, lo, hi - 1, lo + 1, hi // 2, lo // 2]
    ys, xs = zip(*[(y, x) for y in vals for x in vals])
    return {"y": np.array(ys, dtype=np.int64), "x": np.array(xs, dtype=np.int64)}


def _atan2_err(x, got, pm, k):
    fa = k.cfg.frac_angle
    ref = np.arctan2(x["y"].astype(np.float64), x["x"].astype(np.float64))
    err = got["angle"] * 2.0**-fa - ref
    err = (err + np.pi) % (2 * np.pi) - np.pi        # +pi and -pi are the same direction
    return np.abs(err) * 2.0**fa


# ---- rotate ----------------------------------------------------------------------------------

def _rotate_vec(x, pm, k):
    xo, yo, s = V.cordic_rotate(x["x"], x["y"], x["angle"], k)
    return {"x": xo, "y": yo, "saturated": (np.asarray(s) != 0).astype(np.int64)}


def _rotate_scalar(x, pm, k):
    xo, yo, s = M.cordic_rotate(x["x"], x["y"], x["angle"], k)
    return {"x": xo, "y": yo, "saturated": int(bool(s))}


def _rotate_random(rng, n, pm, k):
    f = _field_of(pm, BLOCKS[Block.ROTATE], "angle")
    lo, hi = max(f.lo, -k.pi_a - 4), min(f.hi, k.pi_a + 4)      # |angle| <= pi + a few LSB
    return {"x": _words(rng, n, k.word_min, k.word_max, k), "y": _words(rng, n, k.word_min, k.word_max, k),
            "angle": rng.integers(lo, hi, n, endpoint=True)}


def _rotate_edges(pm, k):
    lo, hi = k.word_min, k.word_max
    q = k.pi_a // 2
    angles = [0, 1, -1, q, -q, q + 1, -q - 1, q - 1, k.pi_a, -k.pi_a, k.pi_a - 1, -k.pi_a + 1, q // 2, -q // 2]
    vecs = [(0, 0), (k.one_u, 0), (hi, 0), (lo, 0), (0, hi), (0, lo), (hi, hi), (lo, lo), (hi, lo), (1, -1)]
    rows = [(vx, vy, a) for vx, vy in vecs for a in angles]
    xs, ys, angs = zip(*rows)
    return {"x": np.array(xs, dtype=np.int64), "y": np.array(ys, dtype=np.int64),
            "angle": np.array(angs, dtype=np.int64)}


def _rotate_err(x, got, pm, k):
    th = x["angle"] * 2.0**-k.cfg.frac_angle
    fx, fy = x["x"].astype(np.float64), x["y"].astype(np.float64)
    rx = np.clip(fx * np.cos(th) - fy * np.sin(th), k.word_min, k.word_max)   # saturation is the spec
    ry = np.clip(fx * np.sin(th) + fy * np.cos(th), k.word_min, k.word_max)
    return np.maximum(np.abs(got["x"] - rx), np.abs(got["y"] - ry))


# ---- sqrt ------------------------------------------------------------------------------------

def _sqrt_frac(pm, k):
    bi, _ = BLOCKS[Block.SQRT].bind(pm)
    return _frac(pm, bi["x"], "i", k.cfg.frac_length)


def _sqrt_vec(x, pm, k):
    return {"root": V.sqrt_word(x["x"], _sqrt_frac(pm, k), k)}


def _sqrt_scalar(x, pm, k):
    return {"root": M.sqrt_word(x["x"], _sqrt_frac(pm, k), k)}


def _sqrt_random(rng, n, pm, k):
    f = _field_of(pm, BLOCKS[Block.SQRT], "x")
    return {"x": _words(rng, n, 0, min(f.hi, k.word_max), k)}


def _sqrt_edges(pm, k):
    f = _field_of(pm, BLOCKS[Block.SQRT], "x")
    hi = min(f.hi, k.word_max)
    fr = _sqrt_frac(pm, k)
    vals = [0, 1, 2, 3, 4, hi, hi - 1, hi // 2, 1 << fr, (1 << fr) - 1, (1 << fr) + 1, 4 << fr] + \
           [(1 << b) - d for b in range(1, k.cfg.width - 1) for d in (0, 1)]
    vals = {v for v in vals if 0 <= v <= hi}
    if f.signed:    # outside the domain, but the model defines the result: the hardware must match
        vals |= {-1, -2, f.lo, f.lo + 1, k.word_min}
    return {"x": np.array(sorted(v for v in vals if f.lo <= v <= f.hi), dtype=np.int64)}


def _sqrt_err(x, got, pm, k):
    fr = _sqrt_frac(pm, k)
    ok = x["x"] >= 0                      # error statistics over the domain only
    ref = np.sqrt(np.where(ok, x["x"], 0) * 2.0**-fr) * 2.0**fr
    return np.abs(got["root"] - ref)[ok]


# ---- acos ------------------------------------------------------------------------------------

def _acos_vec(x, pm, k):
    a, s, sat = V.cordic_acos(x["x"], k)
    return {"angle": a, "sine": s, "saturated": (np.asarray(sat) != 0).astype(np.int64)}


def _acos_scalar(x, pm, k):
    a, s, f = M.cordic_acos(x["x"], k)
    return {"angle": a, "sine": s, "saturated": int(bool(f))}


def _acos_random(rng, n, pm, k):
    inside = rng.integers(-k.one_u, k.one_u, n, endpoint=True)
    near = rng.integers(-64, 65, n) + np.where(rng.random(n) < 0.5, k.one_u, -k.one_u)
    anywhere = rng.integers(k.word_min, k.word_max, n, endpoint=True)
    pick = rng.random(n)
    return {"x": np.where(pick < 0.8, inside, np.where(pick < 0.9, near, anywhere)).astype(np.int64)}


def _acos_edges(pm, k):
    one = k.one_u
    vals = [0, 1, -1, one, -one, one - 1, -one + 1, one + 1, -one - 1, one // 2, -one // 2,
            k.word_max, k.word_min, k.word_max - 1, k.word_min + 1]
    return {"x": np.array(sorted(set(vals)), dtype=np.int64)}


def _acos_err(x, got, pm, k):
    c = np.clip(x["x"] * 2.0**-k.cfg.frac_unit, -1.0, 1.0)
    return np.abs(got["angle"] - np.arccos(c) * 2.0**k.cfg.frac_angle)


# ---- ik (the IK core, hdl/pipelined/core.py) ----------------------------------------------------------

IK_OUTPUTS = SOLUTION_NAMES


def ik_outputs(k, poses: PoseBatch, solve_batch) -> Arrays:
    """``solve_batch`` (``model.solve_batch``, the specification, or ``vector.solve_batch``) over
    ``poses``: the IK core's output fields."""
    q, status = poses.solve(partial(solve_batch, k))
    out = {f"q{j + 1}": np.asarray(q[:, j], dtype=np.int64) for j in range(5)}
    out["status"] = np.asarray(status, dtype=np.int64)
    return out


def _ik_vec(x, pm, k):
    # The C solver (the firmware, a host build): the IK core checked against what the firmware
    # computes, and a third faster than the numpy model in the bulk runs; ``Job.expected``
    # checks it against the scalar model on a sample of every batch, as it did the numpy one.
    return ik_outputs(k, PoseBatch.from_fields(x), csolver.solve_batch)


def _ik_scalar(x, pm, k):
    roll = bool(x["has_roll"])
    pose = M.Pose((x["px"], x["py"], x["pz"]), (x["ax"], x["ay"], x["az"]),
                  (x["nx"], x["ny"], x["nz"]) if roll else None,
                  (x["ox"], x["oy"], x["oz"]) if roll else None)
    joints, status = M.ik_solve(pose, bool(x["shoulder_back"]), bool(x["elbow_down"]),
                                x["q5_default"], k)
    out = {f"q{j + 1}": int(q) for j, q in enumerate(joints)}
    out["status"] = int(status)
    return out


def _ik_random(rng, n, pm, k):
    """Reachable poses (FK of random joints, all branches, with and without roll); one in ten
    rows is random words instead (any input, saturation and invalid paths)."""
    out = vectors.random_poses(k, -(-n // 8), rng)[:n].fields()
    wild = np.flatnonzero(rng.random(n) < 0.1)
    for name in FIELDS:
        f = pm.i.fields[name]
        out[name] = np.array(out[name], dtype=np.int64)      # a copy: the fields may be views
        out[name][wild] = _words(rng, len(wild), max(f.lo, k.word_min), min(f.hi, k.word_max), k)
    return out


def _ik_edges(pm, k):
    return vectors.directed_poses(k).fields()


#: Status bits that make a row's joint error meaningless: no exact solution (unreachable, out of
#: the joint limits), no solution (invalid), a clipped value (saturated), or q1 free (on the base
#: axis with a vertical approach: any q1 solves the pose). SINGULAR_ELBOW stays: it is a valid
#: solution, only worse conditioned (the error grows near it, as the quantisation report shows).
_IK_ERR_EXCLUDE = st.UNREACHABLE | st.INVALID | st.SATURATED | st.SINGULAR_BASE | st.OUT_OF_LIMITS

#: Input quanta of slack for "a unit vector" / "in the arm's plane" (quantising an exact unit
#: vector moves its length by < 1 quantum and its dot products by < 1.5).
_IK_ERR_QUANTA = 4


def _well_formed(a, nv, ov, has_roll, tol):
    """Rows whose approach is a unit vector and, with roll, whose n and o are unit vectors
    orthogonal to each other and to it, all within ``tol``."""
    def unit(v):
        return np.abs(np.linalg.norm(v, axis=1) - 1.0) <= tol

    def orthogonal(u, v):
        return np.abs(np.sum(u * v, axis=1)) <= tol

    return unit(a) & np.where(has_roll, unit(nv) & unit(ov) & orthogonal(nv, ov) & orthogonal(nv, a)
                              & orthogonal(ov, a), True)


def _ik_err(x, got, pm, k):
    """Joint error (LSB of the angle format, worst joint per pose) of the core against the float64
    reference (:func:`ik5r.core.reference.ik`) on the same branch, over the rows where an error means
    something, i.e. the reachable poses the core was built for:

    * well-formed input: the approach is a unit vector and, with roll, n and o are unit vectors
      orthogonal to each other and to it, all within the input quantisation (this drops the
      random-word rows of the stimulus and the raw-word edge rows: zero, 1-LSB, full-scale and
      most-negative vectors, whose direction is not defined to the angle format's precision);
    * reachable: the approach lies in the arm's plane within the quantisation of the tool point
      and the approach (the reference's residual; a pose whose approach the solver has to project
      is a different pose), and the reference's branch has none of the unreachable, invalid,
      saturated, q1-free or out-of-limits bits (:data:`_IK_ERR_EXCLUDE`);
    * the core's status has none of those bits either.

    Differences are wrapped to [-pi, pi) (+pi and -pi are the same joint angle). q5 counts only
    with roll: without n/o both sides just pass ``q5_default`` through. Returns one value per
    kept row (the others are left out, not zero)."""
    from ik5r.core.reference import ik
    c = k.cfg
    fl, fu, fa = c.frac_length, c.frac_unit, c.frac_angle
    n_items = len(x["px"])
    err = np.full(n_items, np.nan)
    p = np.stack([x["px"], x["py"], x["pz"]], axis=1) * 2.0**-fl
    a = np.stack([x["ax"], x["ay"], x["az"]], axis=1) * 2.0**-fu
    nv = np.stack([x["nx"], x["ny"], x["nz"]], axis=1) * 2.0**-fu
    ov = np.stack([x["ox"], x["oy"], x["oz"]], axis=1) * 2.0**-fu
    has_roll = x["has_roll"] != 0
    frame = _well_formed(a, nv, ov, has_roll, _IK_ERR_QUANTA * 2.0**-fu)
    # The arm's plane contains the base axis and the tool point: its angle is known to about one
    # position quantum over the distance from the axis, plus the approach's own quantisation.
    rho = np.hypot(p[:, 0], p[:, 1])
    plane_tol = _IK_ERR_QUANTA * (2.0**-fu + 2.0**-fl / np.maximum(rho, 2.0**-fl))
    hw_ok = (np.asarray(got["status"]) & _IK_ERR_EXCLUDE) == 0
    branch = 2 * x["shoulder_back"] + x["elbow_down"]
    hw = np.stack([got[f"q{j + 1}"] for j in range(5)], axis=1) * 2.0**-fa
    for roll in (True, False):
        rows = np.flatnonzero(has_roll == roll)
        rows = rows[frame[rows] & hw_ok[rows]]
        if not rows.size:
            continue
        near = np.zeros((rows.size, 5))
        near[:, 4] = x["q5_default"][rows] * 2.0**-fa
        res = ik(k.arm, p[rows], a[rows], nv[rows] if roll else None, ov[rows] if roll else None,
                 near=near, singular_sin_q3=c.singular_sin_q3)
        pick = np.arange(rows.size)
        b = branch[rows]
        q_ref = res.q[pick, b]
        ok = ((res.status[pick, b] & _IK_ERR_EXCLUDE) == 0) & (res.residual <= plane_tol[rows])
        d = np.abs((hw[rows] - q_ref + np.pi) % (2 * np.pi) - np.pi)
        joints = 5 if roll else 4
        err[rows] = np.where(ok, d[:, :joints].max(axis=1) * 2.0**fa, np.nan)
    return err[~np.isnan(err)]


BLOCKS: dict[str, BlockSpec] = {
    Block.ATAN2: BlockSpec(Block.ATAN2, {"y": ("y", "y_in"), "x": ("x", "x_in")},
                       {"angle": ("angle", "angle_a", "theta", "z"), "magnitude": ("magnitude", "mag", "r"),
                        "zero": ("zero", "is_zero")},
                       _atan2_vec, _atan2_scalar, _atan2_random, _atan2_edges, _atan2_err),
    Block.ROTATE: BlockSpec(Block.ROTATE, {"x": ("x", "x_in"), "y": ("y", "y_in"), "angle": ("angle", "angle_a", "z")},
                        {"x": ("x", "x_out"), "y": ("y", "y_out"), "saturated": ("saturated", "sat", "flags")},
                        _rotate_vec, _rotate_scalar, _rotate_random, _rotate_edges, _rotate_err),
    Block.SQRT: BlockSpec(Block.SQRT, {"x": ("x", "radicand", "value")}, {"root": ("root", "y", "sqrt", "result")},
                      _sqrt_vec, _sqrt_scalar, _sqrt_random, _sqrt_edges, _sqrt_err),
    Block.ACOS: BlockSpec(Block.ACOS, {"x": ("x", "x_u", "c")},
                      {"angle": ("angle", "angle_a"), "sine": ("sine", "sine_u", "sin", "s"),
                       "saturated": ("saturated", "sat", "flags")},
                      _acos_vec, _acos_scalar, _acos_random, _acos_edges, _acos_err),
    # The IK core: fields are the roles (ik5r.firmware_model.FIELDS, IK_OUTPUTS).
    Block.IK: BlockSpec(Block.IK, {name: (name,) for name in FIELDS},
                    {name: (name,) for name in IK_OUTPUTS},
                    _ik_vec, _ik_scalar, _ik_random, _ik_edges, _ik_err),
}


def get_block(name: str) -> BlockSpec:
    try:
        return BLOCKS[name]
    except KeyError:
        raise ValueError(f"unknown block {name!r}; known: {', '.join(BLOCKS)}") from None
