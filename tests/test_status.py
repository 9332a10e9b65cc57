"""Statuses that say what happened, the same in every layer.

The directed status cases (:mod:`ik5r.core.status_cases`: straight and folded elbow, base axis,
off-plane and non-orthonormal orientations, zero vectors, huge and NaN input) on every branch:
the float reference, the scalar and vectorised fixed-point models, the C solver and the HDL core
(Amaranth simulation) give the same status class; the fixed-point layers the same bits. The seed
paper's check pose is ``singular_elbow`` with joints within 1e-8 rad from every solver.
"""

from __future__ import annotations

import csv

import numpy as np
import pytest

from ik5r.core import reference as ref
from ik5r.core import status as st
from ik5r.core.arm import load_arm
from ik5r.core.fxconfig import constants, load_config
from ik5r.core.status_cases import SEED_CHECK_POSE, status_cases
from ik5r.firmware_model import csolver, model, vector
from ik5r.firmware_model.poses import pose_words
from ik5r.tools.cli import main

ARM = load_arm()
BRANCHES = np.arange(4)


def _float_status(cfg, p, a, n, o):
    with np.errstate(all="ignore"):
        res = ref.ik(ARM, p[None], a[None], None if n is None else n[None], None if o is None else o[None],
                     singular_sin_q3=cfg.singular_sin_q3, reach_tolerance=cfg.reach_tol,
                     orientation_tolerance=cfg.orientation_tolerance)
    return res


def _fixed_args(cfg, p, a, n, o):
    """solve_batch arguments of the four branches of a pose, and the input status per branch."""
    p_l, a_u, n_u, o_u, input_status = pose_words(cfg, p[None], a[None], None if n is None else n[None],
                                                  None if o is None else o[None])
    rows = [0] * 4
    zeros = np.zeros((4, 3), dtype=np.int64)
    args = (p_l[rows], a_u[rows], zeros if n_u is None else n_u[rows], zeros if o_u is None else o_u[rows],
            np.full(4, n is not None), (BRANCHES & 2) != 0, (BRANCHES & 1) != 0, np.zeros(4, np.int64))
    return args, input_status[rows]


def _with_input(status, input_status):
    status = np.asarray(status, dtype=np.int64)
    return np.where(input_status != 0, input_status, status)


def status_table(name: str):
    """[(case, expected, chosen branch, {layer: [class per branch]}, model bits, fixed args)]."""
    cfg = load_config(name)
    k = constants(cfg, ARM)
    c_solver = csolver.solver(k)
    table = []
    for case, expected, (p, a, n, o) in status_cases(ARM):
        res = _float_status(cfg, p, a, n, o)
        args, input_status = _fixed_args(cfg, p, a, n, o)
        bits = {"fixed (model)": _with_input(model.solve_batch(k, *args)[1], input_status),
                "fixed (vector)": _with_input(vector.solve_batch(k, *args)[1], input_status),
                "c": _with_input(c_solver.solve_batch(*args)[1], input_status)}
        classes = {"float": [st.status_class(s) for s in res.status[0]]}
        classes.update({layer: [st.status_class(s) for s in b] for layer, b in bits.items()})
        table.append((case, expected, int(res.choose()[0]), classes, bits["fixed (model)"], (args, input_status)))
    return table


def _print(name, table):
    print(f"\ndirected status table, config {name} (class per branch 0..3; float = fixed = C):")
    for case, expected, chosen, classes, _, _ in table:
        print(f"  {case:52s} chosen {chosen}: {classes['float'][chosen]:16s} branches {classes['float']}")


@pytest.mark.parametrize("name", ["q32w", "q18"])
def test_directed_status_classes_agree(name):
    table = status_table(name)
    _print(name, table)
    disagreements = [(case, layer, classes[layer], classes["float"]) for case, _, _, classes, _, _ in table
                     for layer in classes if classes[layer] != classes["float"]]
    assert disagreements == []
    for case, expected, chosen, classes, bits, _ in table:
        assert expected in classes["float"], case       # e.g. the branch of the pose's own joints
        assert np.all(bits < 1 << 6) and not np.any(bits & st.OUT_OF_LIMITS)
    seen = {cls for _, _, _, classes, _, _ in table for cls in classes["float"]}
    assert {"ok", "singular_elbow", "singular_base", "unreachable+singular_elbow", "bad_orientation",
            "invalid"} <= seen


@pytest.mark.parametrize("arch", ["pipelined", "compact"])
def test_directed_status_hdl_core(arch):
    """The HDL core (Amaranth simulation, q18, ``hdl.generate``'s archs: pipelined, compact = the
    sequenced engine) on the cases' words: the model's bits, so the float's class."""
    from ik5r.hdl.generate import build
    from ik5r.tools.testbench.amaranth_stream import run_stream

    table = status_table("q18")
    k = constants(load_config("q18"), ARM)
    items, expected, classes = [], [], []
    names = ("px", "py", "pz", "ax", "ay", "az", "nx", "ny", "nz", "ox", "oy", "oz")
    for _, _, _, layer_classes, bits, (args, input_status) in table:
        p_l, a_u, n_u, o_u, roll, back, down, q5 = args
        for b in range(4):
            words = [*p_l[b], *a_u[b], *n_u[b], *o_u[b]]
            item = dict(zip(names, (int(w) for w in words)))
            item.update(has_roll=int(roll[b]), shoulder_back=int(back[b]), elbow_down=int(down[b]),
                        q5_default=int(q5[b]))
            items.append(item)
            expected.append(int(model.solve_batch(k, *(v[b:b + 1] for v in args))[1][0]))
            classes.append((layer_classes["float"][b], int(input_status[b])))
    outputs, _, _ = run_stream(build("ik", arch, k), items)
    got = [int(out["status"]) for out in outputs]
    assert got == expected
    hdl_classes = [st.status_class(input_bits or bits) for bits, (_, input_bits) in zip(got, classes)]
    assert hdl_classes == [cls for cls, _ in classes]


@pytest.mark.parametrize("solver", ["float", "fixed", "c"])
def test_seed_check_pose_is_singular_elbow(tmp_path, solver):
    """``ik5r fk`` then ``ik5r solve`` of q = [0, -pi/2, 0, -pi/2, 0] (default config q32w)."""
    joints = tmp_path / "j.csv"
    joints.write_text("q1,q2,q3,q4,q5\n" + ",".join(repr(v) for v in SEED_CHECK_POSE) + "\n")
    poses = tmp_path / "p.csv"
    assert main(["fk", str(joints), "-o", str(poses)]) == 0
    out = tmp_path / "o.csv"
    assert main(["solve", str(poses), "-o", str(out), "--solver", solver]) == 0
    with open(out, newline="") as handle:
        (row,) = list(csv.DictReader(handle))
    assert row["status"] == "singular_elbow"
    q = np.array([float(row[f"q{j}"]) for j in range(1, 6)])
    assert np.abs(ref.wrap(q - np.array(SEED_CHECK_POSE))).max() <= 1e-8
    assert float(row["residual_cm"]) <= 1e-7 and float(row["residual_rad"]) <= 1e-8


def test_reach_tolerance_boundary():
    """Just inside the reach tolerance: singular_elbow (clipped); just beyond it: unreachable, in
    the float reference and the fixed-point model alike (q32w)."""
    cfg = load_config("q32w")
    k = constants(cfg, ARM)
    p, n, o, a = ref.fk(ARM, np.array(SEED_CHECK_POSE))
    # c3 - 1 ~ (a2 + a3) dz / (a2 a3): move the tool point up by a fraction of the tolerance.
    step = cfg.reach_tol * ARM.a[1] * ARM.a[2] / (ARM.a[1] + ARM.a[2])
    for factor, want in ((0.5, "singular_elbow"), (2.0, "unreachable+singular_elbow")):
        q = p + np.array([0, 0, factor * step])
        res = _float_status(cfg, q, a, n, o)
        assert st.status_class(res.status[0, 2]) == want
        args, _ = _fixed_args(cfg, q, a, n, o)
        assert st.status_class(vector.solve_batch(k, *args)[1][2]) == want
