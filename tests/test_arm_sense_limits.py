"""Issue 26's rest of the family: a joint whose positive sense is reversed (``scale = -1``) and
joint limits as the ``out_of_limits`` status, in every layer: the float reference, the C solver,
the scalar and the vectorised model (bit for bit) and the traced graph both IK cores are built
from. An arm whose limits are all full turns gets no limit check at all (its cores are
byte-identical to what they were; ``ik5r verilog`` before/after, in the branch's closing note).
The cores' cocotb runs on an arm with limits are in tests/test_cocotb_arms.py (scorbot-er4u)."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pytest

from ik5r.core import reference as ref
from ik5r.core import status as st
from ik5r.core.arm import load_arm, parse_arm
from ik5r.core.errors import InputError
from ik5r.core.fxconfig import Constants, load_config
from ik5r.firmware_model import csolver, model, vector
from ik5r.firmware_model.poses import PoseBatch

#: A test arm with reversed joints and limits (its file says which).
REVERSED_PATH = Path(__file__).parent / "arms" / "scorbot-reversed.toml"
REVERSED_TOML = REVERSED_PATH.read_text()


@functools.cache
def reversed_arm():
    import tomllib

    return parse_arm(tomllib.loads(REVERSED_TOML), "scorbot-reversed.toml")


def _unreversed(arm):
    """The same arm with every joint counted the closed form's way."""
    from dataclasses import replace

    return replace(arm, sense=(1,) * 5, limits=((-np.pi, np.pi),) * 5)


def test_scale_is_read_and_checked():
    import tomllib

    arm = reversed_arm()
    assert arm.sense == (1, -1, -1, -1, -1)
    assert arm.dh_sha256() != _unreversed(arm).dh_sha256()
    # An arm with no reversed joint keeps the hash it had before senses existed (main, cdfb8b3).
    assert load_arm("hu-5r").dh_sha256() == "14958c8210da6100"
    assert "sense" not in load_arm("hu-5r").fields() and "sense" in arm.fields()
    bad = REVERSED_TOML.replace("scale = -1\nlimits = [-35, 130]", "scale = 2\nlimits = [-35, 130]")
    with pytest.raises(InputError, match="must be 1 or -1"):
        parse_arm(tomllib.loads(bad), "bad.toml")


def test_fk_of_a_reversed_joint_is_the_dh_joint_negated():
    arm = reversed_arm()
    rng = np.random.default_rng(3)
    q = rng.uniform(-np.pi, np.pi, (200, 5))
    flipped = q * np.array(arm.sense)
    for mine, plain in zip(ref.fk(arm, q), ref.fk(_unreversed(arm), flipped)):
        np.testing.assert_allclose(mine, plain, atol=1e-12)
    np.testing.assert_allclose(ref.fk_matrix(arm, q)[:, :3, 3], ref.fk(arm, q)[0], atol=1e-12)


def _random_in_limits(arm, count, seed):
    q = ref.random_joints(arm, count, np.random.default_rng(seed))
    lo, hi = arm.lower, arm.upper
    assert np.all((q >= lo) & (q <= hi))
    return q


def _matching_branch(arm, q):
    """The float reference's IK of FK(q): per pose the branch that gives q back (the one of q's
    own configuration), its error and whether it is a clean solution."""
    p, n, o, a = ref.fk(arm, q)
    res = ref.ik(arm, p, a, n, o)
    err = np.abs(ref.wrap(res.q - q[:, None, :])).max(axis=2)
    branch = np.argmin(err, axis=1)
    rows = np.arange(len(q))
    clean = (res.status[rows, branch] & ~(st.SINGULAR_ELBOW | st.SINGULAR_BASE)) == 0
    return (p, n, o, a), branch, err[rows, branch], clean


def test_reversed_arm_round_trip_float_reference():
    """FK of random joints within the limits, IK: one clean branch gives the joints back."""
    arm = reversed_arm()
    _, _, err, clean = _matching_branch(arm, _random_in_limits(arm, 2000, 5))
    assert clean.mean() > 0.99
    assert err[clean].max() < 1e-7, err[clean].max()


def _solvers(k):
    return {"c": csolver.solver(k).solve_batch, "scalar": functools.partial(model.solve_batch, k),
            "vector": functools.partial(vector.solve_batch, k)}


def _all_layers(k, poses):
    """(q, status) of the C solver, asserting the scalar and the vectorised model give every bit."""
    out = {name: tuple(np.asarray(v, dtype=np.int64) for v in poses.solve(fn)) for name, fn in _solvers(k).items()}
    for name in ("scalar", "vector"):
        np.testing.assert_array_equal(out[name][0], out["c"][0], err_msg=f"{name} joints")
        np.testing.assert_array_equal(out[name][1], out["c"][1], err_msg=f"{name} status")
    return out["c"]


def test_reversed_arm_round_trip_fixed_point_layers():
    """FK -> IK -> joints back in C, the scalar and the vectorised model (bit-identical), on the
    branch of the joints' own configuration: the tool point within the error floor, and each
    reversed joint's word the negated word of the same arm counted the closed form's way (to
    the rounding of a tie, 1 LSB), the others the same words."""
    from ik5r.tools.arm_accuracy import ERROR_FLOOR_PER_REACH

    arm = reversed_arm()
    k = Constants(load_config("q32w"), arm)
    q = _random_in_limits(arm, 600, 7)
    (p, n, o, a), branch, _, _ = _matching_branch(arm, q)
    poses, input_status = PoseBatch.quantise(k.cfg, p, a, n, o)
    assert not input_status.any()
    q_raw, status = _all_layers(k, poses.with_branch(branch))
    good = (status & ~(st.SINGULAR_ELBOW | st.SINGULAR_BASE)) == 0
    assert good.mean() > 0.99
    got = q_raw * 2.0 ** -k.cfg.frac_angle
    assert np.median(np.abs(ref.wrap(got - q))) < 1e-8
    reached = ref.fk(arm, got[good])[0]
    assert np.abs(reached - p[good]).max() <= ERROR_FLOOR_PER_REACH * arm.reach
    plain_raw, plain_status = _all_layers(Constants(k.cfg, _unreversed(arm)), poses.with_branch(branch))
    np.testing.assert_array_equal(status & ~st.OUT_OF_LIMITS, plain_status)
    sense = np.array(arm.sense)
    diff = q_raw - sense * plain_raw
    assert np.all(np.abs(diff) <= 1) and np.all(diff[:, sense > 0] == 0)
    # Ties (the internal guard bits all 10...0, the rounding goes up either way) are rare.
    assert np.mean(diff == 0) > 0.95


def _outside(k, q_raw):
    """Rows whose output words pass a limit of the arm, by the arm file's numbers (radians)."""
    q = q_raw * 2.0 ** -k.cfg.frac_angle
    limited = np.array([not (lo <= -np.pi and hi >= np.pi) for lo, hi in k.arm.limits])
    return (((q < k.arm.lower) | (q > k.arm.upper)) & limited).any(axis=1)


@pytest.mark.parametrize("name", ["scorbot-er4u", "reversed"])
def test_out_of_limits_in_every_software_layer(name):
    """Every branch of random poses: the status bit in C == scalar == vectorised, set exactly
    where an output joint passes a limit (some rows each way)."""
    from ik5r.firmware_model.vectors import random_poses

    arm = reversed_arm() if name == "reversed" else load_arm(name)
    k = Constants(load_config("q32w"), arm)
    poses = random_poses(k, 500, seed=11)
    q_raw, status = _all_layers(k, poses)
    flagged = (status & st.OUT_OF_LIMITS) != 0
    np.testing.assert_array_equal(flagged, _outside(k, q_raw))
    assert 0.05 < flagged.mean() < 0.95


def test_full_turn_arms_have_no_limit_check():
    from ik5r.firmware_model.vectors import random_poses

    for name in ("hu-5r", "youbot-arm", "al5d", "px150"):
        k = Constants(load_config("q32w"), load_arm(name))
        assert not k.limited and k.status_width == 6
        _, status = _all_layers(k, random_poses(k, 100, seed=1))
        assert not np.any(status & st.OUT_OF_LIMITS)
    assert Constants(load_config("q32w"), load_arm("scorbot-er4u")).status_width == 7


def test_limits_that_cross_the_half_turn_are_refused():
    import tomllib

    doc = tomllib.loads(REVERSED_TOML.replace("limits = [-155, 155]", "limits = [-200, 100]"))
    arm = parse_arm(doc, "wrapped.toml")
    with pytest.raises(InputError, match="cross"):
        Constants(load_config("q32w"), arm)


def test_status_class_keeps_out_of_limits():
    """The float reference and the fixed-point solvers name a branch out of limits alike, away
    from the limits' edges (within an LSB of a limit the rounded words may differ)."""
    arm = load_arm("scorbot-er4u")
    k = Constants(load_config("q32w"), arm)
    q = np.array([[0.2, 0.3, np.radians(150), 0.2, 0.1], [0.2, 0.3, np.radians(100), 0.2, 0.1]])
    p, n, o, a = ref.fk(arm, q)
    res = ref.ik(arm, p, a, n, o)
    poses, _ = PoseBatch.quantise(k.cfg, p, a, n, o)
    _, status = _all_layers(k, poses.with_branch(np.zeros(2, dtype=int)))
    assert [st.status_class(s) for s in status] == [st.status_class(s) for s in res.status[:, 0]]
    assert st.status_class(status[0]) == "out_of_limits" and st.status_class(status[1]) == "ok"


def test_traced_graph_checks_only_limited_sides():
    """The graph both cores are built from: no limit compare for a full-turn arm, one per side
    of a limit inside the turn otherwise (scorbot-er4u: joints 1, 3, 4, two sides each)."""
    from ik5r.hdl.graph.inputs import core_fields
    from ik5r.hdl.graph.trace import trace

    def limit_leaves(arm):
        k = Constants(load_config("q32w"), arm)
        _, events, _ = trace(k)
        return [leaf for leaf in events if leaf.bit == st.OUT_OF_LIMITS], core_fields(k)[1]["status"][0]

    leaves, shape = limit_leaves(load_arm("hu-5r"))
    assert leaves == [] and shape.width == 6
    leaves, shape = limit_leaves(load_arm("scorbot-er4u"))
    assert len(leaves) == 6 and shape.width == 7
    assert len(limit_leaves(reversed_arm())[0]) == 8


@pytest.mark.parametrize("name", ["scorbot-er4u", "reversed"])
def test_c_clean_with_limits_and_reversed_joints(name):
    """The C with the limit tables and senses in its header: strict warnings clean, the
    ASan + UBSan test driver bit-exact to the vectorised model (out_of_limits among its bits), and
    it builds for rv32im."""
    from ik5r.firmware_model import rv32
    from ik5r.firmware_model.poses import concat
    from ik5r.firmware_model.vectors import edge_poses, random_poses

    arm = reversed_arm() if name == "reversed" else load_arm(name)
    k = Constants(load_config("q32w"), arm)
    result = csolver.warnings_check(k)
    assert result.returncode == 0 and not result.stderr, result.stderr
    poses = concat(random_poses(k, 100, seed=3), edge_poses(k))
    out = csolver.run_test_driver(csolver.build_test_driver(k, sanitize=True), poses.driver_lines())
    rows = np.array([list(map(int, line.split())) for line in out], dtype=np.int64)
    q, status = (np.asarray(v, dtype=np.int64) for v in vector.solve_batch(k, *poses.args()))
    np.testing.assert_array_equal(rows[:, :5], q)
    np.testing.assert_array_equal(rows[:, 5], status)
    assert np.any(status & st.OUT_OF_LIMITS)
    assert rv32.build(k, "rv32im").elf.is_file()


@pytest.mark.parametrize("solver", ["float", "fixed", "c"])
def test_solve_without_roll_reads_q5_from_near(solver, tmp_path):
    """Poses without n, o: every solver answers q5 = --near's q5 on an arm whose joint 5 is
    reversed and offset (the solvers' q5 input word is the DH angle the reading makes)."""
    import csv

    from ik5r.tools.cli import main

    arm = reversed_arm()
    q = np.array([[0.2, 0.3, 0.5, -0.4, 0.0], [-0.3, 0.1, 0.8, 0.2, 0.0]])
    p, _, _, a = ref.fk(arm, q)
    rows = ["px,py,pz,ax,ay,az"] + [",".join(repr(float(v)) for v in (*p[i], *a[i])) for i in range(2)]
    (tmp_path / "poses.csv").write_text("\n".join(rows) + "\n")
    out = tmp_path / "out.csv"
    assert main(["solve", str(tmp_path / "poses.csv"), "--solver", solver, "--arm", str(REVERSED_PATH),
                 "--near=0.2,0.3,0.5,-0.4,0.7", "-o", str(out)]) == 0
    got = list(csv.DictReader(open(out)))
    assert [r["status"] for r in got] == ["ok", "ok"]
    np.testing.assert_allclose([float(r["q5"]) for r in got], [0.7, 0.7], atol=1e-8)
    np.testing.assert_allclose([float(got[0][f"q{j}"]) for j in range(1, 5)], q[0, :4], atol=1e-6)
