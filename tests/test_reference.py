"""The float reference (ik5r.core.reference): FK against roboticstoolbox, the paper's check, IK round
trips over the joint space, directed statuses, branch choice, joint limits and arm TOML errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ik5r.core import reference as ref
from ik5r.core import status as st
from ik5r.core.arm import load_arm
from ik5r.core.errors import InputError
from ik5r.core.reference_check import sincos

ARM = load_arm()
HARMLESS = st.SINGULAR_ELBOW | st.SINGULAR_BASE
#: The FK of every returned valid branch must give the tool point back within this (cm).
POSITION_TOL_CM = 1e-9
#: The original joints must be among the valid branches within this (rad, wrapped, per joint).
JOINT_TOL_RAD = 1e-7


def _rtb_robot(arm):
    rtb = pytest.importorskip("roboticstoolbox")
    links = [rtb.RevoluteDH(d=arm.d[i], a=arm.a[i], alpha=arm.alpha[i], offset=arm.theta_offset[i])
             for i in range(5)]
    return rtb.DHRobot(links, name=arm.name)


def _arm_toml(tmp_path, limits=None, offsets=None, name="arm.toml", override=None):
    """An arm TOML of the arm of record; ``override``: {joint index: {key: TOML text or None}}."""
    override = override or {}
    a = [1.1, 10, 9.5, 3.2, 0]
    alpha = [-90, 0, 0, -90, 0]
    d = [0, 0, 0, 0, 14.5]
    lines = ['name = "test"', 'length_unit = "cm"', 'angle_unit = "deg"']
    for i in range(5):
        lines.append("[[joint]]")
        values = {"a": a[i], "alpha": alpha[i], "d": d[i], "theta_offset": (offsets or [0] * 5)[i]}
        values.update(override.get(i, {}))
        for key, value in values.items():
            if value is not None:
                lines.append(f"{key} = {value}")
        if limits and limits[i] is not None:
            lines.append(f"limits = [{limits[i][0]}, {limits[i][1]}]")
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n")
    return path


# ------------------------------------------------------------------------------------------
# Forward kinematics


@pytest.mark.parametrize("offsets", [None, [10, -20, 30, 45, -60]])
def test_fk_matches_roboticstoolbox(tmp_path, offsets):
    arm = load_arm(_arm_toml(tmp_path, offsets=offsets)) if offsets else ARM
    robot = _rtb_robot(arm)
    q = ref.random_joints(arm, 3000, np.random.default_rng(11))
    t_rtb = np.array(robot.fkine(q).A)
    p, n, o, a = ref.fk(arm, q)
    assert np.abs(p - t_rtb[:, :3, 3]).max() <= 1e-12
    assert np.abs(n - t_rtb[:, :3, 0]).max() <= 1e-14
    assert np.abs(o - t_rtb[:, :3, 1]).max() <= 1e-14
    assert np.abs(a - t_rtb[:, :3, 2]).max() <= 1e-14
    # the product of the DH matrices agrees too
    t = ref.fk_matrix(arm, q)
    assert np.abs(t[:, :3, 3] - t_rtb[:, :3, 3]).max() <= 1e-12
    assert np.abs(t[:, :3, :3] - t_rtb[:, :3, :3]).max() <= 1e-14
    pose = ref.fk_pose(arm, q)
    assert pose.shape == (3000, 12)
    assert np.array_equal(pose, np.concatenate([p, n, o, a], axis=1))


def test_paper_check():
    q = np.array([0.0, -math.pi / 2, 0.0, -math.pi / 2, 0.0])
    p, n, o, a = ref.fk(ARM, q)
    assert np.allclose(p, [-2.1, 0.0, 34.0], rtol=0, atol=1e-12)
    assert np.allclose(a, [0.0, 0.0, 1.0], rtol=0, atol=1e-12)
    res = ref.ik(ARM, p, a, n, o)
    valid = res.valid[0]
    dq = np.abs(ref.wrap(res.q[0] - q)).max(axis=-1)
    assert np.any(valid & (dq <= 1e-12))
    # the arm stretched straight up: the elbow is straight
    assert np.all(res.status[0][valid] & st.SINGULAR_ELBOW)


def test_sincos_matches_numpy():
    rng = np.random.default_rng(5)
    x = np.concatenate([rng.uniform(-2 * np.pi, 2 * np.pi, 1_000_000),
                        np.linspace(-2 * np.pi, 2 * np.pi, 100_001),
                        [0.0, -0.0, np.pi, -np.pi, np.pi / 2, -np.pi / 2, 1e-300]])
    s, c = sincos(x)
    assert np.abs(s - np.sin(x)).max() <= 5e-16
    assert np.abs(c - np.cos(x)).max() <= 5e-16


# ------------------------------------------------------------------------------------------
# Round trip over the joint space


def _round_trip(arm, count, seed, roll=True):
    q = ref.random_joints(arm, count, np.random.default_rng(seed))
    p, n, o, a = ref.fk(arm, q)
    res = ref.ik(arm, p, a, n, o) if roll else ref.ik(arm, p, a, near=np.zeros(5))
    valid = res.valid
    # every returned valid branch reproduces the tool point (FK independent of the IK's check)
    p_back = ref.fk(arm, np.where(valid[..., None], res.q, 0.0))[0]
    err = np.linalg.norm(p_back - p[:, None, :], axis=-1)
    assert err[valid].max() <= POSITION_TOL_CM
    # the approach too
    a_back = ref.fk(arm, np.where(valid[..., None], res.q, 0.0))[3]
    assert np.abs(a_back - a[:, None, :])[valid].max() <= 1e-12
    # the original joints are among the valid branches (q5 only when n, o are given)
    joints = slice(None) if roll else slice(0, 4)
    dq = np.abs(ref.wrap(res.q - q[:, None, :]))[..., joints].max(axis=-1)
    best = np.where(valid, dq, np.inf).min(axis=1)
    assert best.max() <= JOINT_TOL_RAD, f"{np.count_nonzero(best > JOINT_TOL_RAD)} poses lost"
    assert np.all(res.residual <= 1e-12)
    assert not res.q1_free.any()
    return res


def test_round_trip_100k():
    res = _round_trip(ARM, 100_000, seed=1)
    # random joints give no pose on the base axis, no off-plane approach, nothing out of limits
    assert set(np.unique(res.status).tolist()) <= {0, st.SINGULAR_ELBOW, st.UNREACHABLE,
                                                   st.UNREACHABLE | st.SINGULAR_ELBOW}
    assert res.valid.all(axis=1).mean() > 0.5


def test_round_trip_without_roll():
    res = _round_trip(ARM, 20_000, seed=2, roll=False)
    assert np.all(res.q[..., 4][res.valid] == 0.0)


def test_round_trip_with_offsets_and_float32(tmp_path):
    arm = load_arm(_arm_toml(tmp_path, offsets=[10, -20, 30, 45, -60]))
    _round_trip(arm, 20_000, seed=3)
    q = ref.random_joints(ARM, 20_000, np.random.default_rng(4))
    p, n, o, a = ref.fk(ARM, q)
    r32 = ref.ik(ARM, p, a, n, o, dtype=np.float32)
    assert r32.q.dtype == np.float32
    dq = np.abs(ref.wrap(r32.q.astype(np.float64) - q[:, None, :])).max(axis=-1)
    best = np.where(r32.valid, dq, np.inf).min(axis=1)
    assert np.mean(best <= 1e-3) >= 0.999


@pytest.mark.slow
def test_round_trip_1m():
    _round_trip(ARM, 1_000_000, seed=7)


# ------------------------------------------------------------------------------------------
# Directed poses


def _pose(q):
    p, n, o, a = ref.fk(ARM, np.asarray(q, dtype=float))
    return p, n, o, a


def _has_original(res, q, tol=JOINT_TOL_RAD):
    dq = np.abs(ref.wrap(res.q[0] - np.asarray(q))).max(axis=-1)
    hit = res.valid[0] & (dq <= tol)
    return np.flatnonzero(hit)


def test_unreachable_far():
    res = ref.ik(ARM, [100.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    assert np.all(res.status[0] & st.UNREACHABLE)
    assert not res.valid.any()
    assert np.all(np.abs(res.q[0, :, 2]) == 0.0)   # elbow clipped straight


def test_unreachable_too_near():
    # wrist centre 0.2 cm from joint 2 (below |a2 - a3| = 0.5) in front; approach horizontal +x
    p, a = [0.2 + 1.1 + 14.5, 0.0, 3.2], [1.0, 0.0, 0.0]
    res = ref.ik(ARM, p, a)
    assert np.all(res.status[0, :2] & st.UNREACHABLE)
    assert np.allclose(np.abs(res.q[0, :2, 2]), math.pi, rtol=0, atol=1e-12)   # folded
    # behind the base the same tool point is reachable
    assert res.valid[0, 2:].all()


def test_straight_and_folded_elbow():
    for q3 in (0.0, math.pi, -math.pi + 1e-4):
        q = [0.3, -0.5, q3, 0.4, 0.1]
        p, n, o, a = _pose(q)
        res = ref.ik(ARM, p, a, n, o)
        hits = _has_original(res, q)
        assert hits.size, q3
        assert np.all(res.status[0, hits] == st.SINGULAR_ELBOW)


def test_base_axis_vertical_approach_is_singular_base():
    p, a = [0.0, 0.0, 10.0], [0.0, 0.0, 1.0]
    near = [0.7, 0.0, 0.0, 0.0, 0.2]
    res = ref.ik(ARM, p, a, near=near)
    assert res.q1_free[0]
    assert np.all(res.status[0] == st.SINGULAR_BASE)
    assert res.valid[0].all()
    assert res.q[0, 0, 0] == 0.7 and res.q[0, 1, 0] == 0.7
    assert np.allclose(res.q[0, 2:, 0], 0.7 - math.pi, rtol=0, atol=1e-15)
    assert np.all(res.q[0, :, 4] == 0.2)
    p_back, _, _, a_back = ref.fk(ARM, res.q[0])
    assert np.abs(p_back - p).max() <= POSITION_TOL_CM
    assert np.abs(a_back - a).max() <= 1e-12
    # without near: q1 = 0
    res0 = ref.ik(ARM, p, a)
    assert res0.q1_free[0] and res0.q[0, 0, 0] == 0.0


def test_base_axis_horizontal_approach():
    angle = 0.4
    p, a = [0.0, 0.0, 3.2], [math.cos(angle), math.sin(angle), 0.0]
    res = ref.ik(ARM, p, a)
    assert not res.q1_free[0]
    assert np.all(res.status[0] == 0)
    assert res.q[0, 0, 0] == pytest.approx(angle, abs=1e-15)
    p_back, _, _, a_back = ref.fk(ARM, res.q[0])
    assert np.abs(p_back - p).max() <= POSITION_TOL_CM
    assert np.abs(a_back - a).max() <= 1e-12


def test_off_plane_approach_residual():
    q = [0.6, -0.7, 1.1, 0.5, 0.0]
    p, _, _, a = _pose(q)
    normal = np.array([-math.sin(q[0]), math.cos(q[0]), 0.0])   # perpendicular to the arm's plane
    tilt = 0.25
    a_off = math.cos(tilt) * a + math.sin(tilt) * normal
    res = ref.ik(ARM, p, a_off)
    assert res.residual[0] == pytest.approx(tilt, abs=1e-12)
    # 0.25 rad off the plane: beyond the orientation tolerance, every branch says so ...
    assert np.all(res.status[0] & st.BAD_ORIENTATION)
    assert not res.valid[0].any()
    # ... and solves the projected approach: the branches valid but for that bit.
    solved = (res.status[0] & ~(st.BAD_ORIENTATION | st.SINGULAR_ELBOW | st.SINGULAR_BASE)) == 0
    dq = np.abs(ref.wrap(res.q[0] - np.asarray(q))).max(axis=-1)
    assert np.any(solved & (dq <= JOINT_TOL_RAD))
    assert solved[res.choose()[0]]
    p_back, _, _, a_back = ref.fk(ARM, res.q[0][solved])
    assert np.abs(p_back - p).max() <= POSITION_TOL_CM
    assert np.abs(a_back - a).max() <= 1e-12        # the projection, not the given approach


def test_orientation_tolerance_boundary():
    """An approach off the plane by less than the tolerance is ok, by more bad_orientation; a frame
    rotated, skewed or mirrored beyond it too; the default tolerance is 1e-3."""
    q = [0.6, -0.7, 1.1, 0.5, 0.2]
    p, n, o, a = _pose(q)
    normal = np.array([-math.sin(q[0]), math.cos(q[0]), 0.0])
    for sine, bad in ((0.5e-3, False), (2e-3, True)):
        a_off = math.sqrt(1 - sine * sine) * a + sine * normal
        res = ref.ik(ARM, p, a_off)
        assert bool(np.all(res.status[0] & st.BAD_ORIENTATION)) is bad
        assert bool(np.any(res.status[0] & st.BAD_ORIENTATION)) is bad
    assert not np.any(ref.ik(ARM, p, a, n, o).status[0] & st.BAD_ORIENTATION)
    for n2, o2 in ((n, -o), (o, n), (n, (o + 2e-3 * n) / np.linalg.norm(o + 2e-3 * n)), (1.002 * n, o)):
        assert np.all(ref.ik(ARM, p, a, n2, o2).status[0] & st.BAD_ORIENTATION)
    assert np.all(ref.ik(ARM, p, a, n, (o + 5e-4 * n) / np.linalg.norm(o + 5e-4 * n)).status[0]
                  & st.BAD_ORIENTATION) == 0


def test_huge_input_is_invalid_not_nan_status():
    res = ref.ik(ARM, [1e155, 0.0, 0.0], [0.0, 0.0, 1.0])
    assert np.all(res.status[0] == st.INVALID) and np.isnan(res.q[0]).all()
    res = ref.ik(ARM, [1e150, 0.0, 0.0], [0.0, 0.0, 1.0])          # large but squarable: unreachable
    assert np.all(res.status[0] & st.UNREACHABLE) and not np.any(res.status[0] & st.INVALID)


def test_perpendicular_approach_is_invalid():
    res = ref.ik(ARM, [20.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    assert np.all(res.status[0] == st.INVALID)
    assert res.residual[0] == pytest.approx(math.pi / 2)
    assert np.isnan(res.q[0]).all()


def test_nan_row_is_invalid_others_solved():
    q = ref.random_joints(ARM, 5, np.random.default_rng(9))
    p, n, o, a = ref.fk(ARM, q)
    alone = ref.ik(ARM, p, a, n, o)
    for field in ("p", "a", "n", "o"):
        bad = {"p": p.copy(), "a": a.copy(), "n": n.copy(), "o": o.copy()}
        bad[field][2, 1] = np.nan if field != "o" else np.inf
        res = ref.ik(ARM, bad["p"], bad["a"], bad["n"], bad["o"])
        assert np.all(res.status[2] == st.INVALID)
        assert np.isnan(res.q[2]).all() and np.isnan(res.residual[2])
        keep = [0, 1, 3, 4]
        assert np.array_equal(res.status[keep], alone.status[keep])
        assert np.array_equal(res.q[keep], alone.q[keep])


def test_choose_default_and_near():
    q = [-2.5, 1.0, -2.0, 0.3, 3.0]         # the front-shoulder elbow-down branch
    p, n, o, a = _pose(q)
    res = ref.ik(ARM, p, a, n, o)
    assert res.valid[0].all()
    assert res.choose()[0] == 0            # documented default: first valid (front, elbow up)
    assert res.choose(q)[0] == 1
    for b in range(4):
        assert res.choose(res.q[0, b] + 0.01)[0] == b
    q_best, s_best, branch = res.best(q)
    assert branch[0] == 1 and s_best[0] == 0
    assert np.abs(ref.wrap(q_best[0] - q)).max() <= JOINT_TOL_RAD
    # per-pose near (N, 5)
    res2 = ref.ik(ARM, *(np.tile(v, (2, 1)) for v in (p, a, n, o)))
    assert res2.choose(np.stack([res.q[0, 3], res.q[0, 2]])).tolist() == [3, 2]
    # no valid branch: branch 0
    far = ref.ik(ARM, [100.0, 0, 0], [0, 0, 1.0])
    assert far.choose()[0] == 0 and far.choose(q)[0] == 0


def test_near_wraps_at_pi():
    q = [math.pi - 1e-3, 0.2, 0.9, -0.4, -math.pi + 1e-3]
    p, n, o, a = _pose(q)
    res = ref.ik(ARM, p, a, n, o)
    b = res.choose([-math.pi + 1e-3, 0.2, 0.9, -0.4, math.pi - 1e-3])[0]
    assert np.abs(ref.wrap(res.q[0, b] - q)).max() <= JOINT_TOL_RAD


# ------------------------------------------------------------------------------------------
# Joint limits and arm TOML


def test_joint_limits_filter_branches(tmp_path):
    arm = load_arm(_arm_toml(tmp_path, limits=[None, None, (0, 180), None, None]))
    q = ref.random_joints(ARM, 5000, np.random.default_rng(12))
    p, n, o, a = ref.fk(arm, q)
    res = ref.ik(arm, p, a, n, o)
    reachable = (res.status & st.UNREACHABLE) == 0
    down = np.array([False, True, False, True])
    q3 = res.q[..., 2]
    flagged = (res.status & st.OUT_OF_LIMITS) != 0
    assert np.array_equal(flagged & reachable, ((q3 < -1e-12) | (q3 > math.pi + 1e-12)) & reachable)
    assert not res.valid[:, down].any() or np.all(np.abs(q3[:, down][res.valid[:, down]]) <= 1e-12)
    assert np.all(q3[res.valid] >= -1e-12)
    # the originals with q3 >= 0 are still found; those with q3 < 0 are not solvable within limits
    dq = np.abs(ref.wrap(res.q - q[:, None, :])).max(axis=-1)
    best = np.where(res.valid, dq, np.inf).min(axis=1)
    assert np.all(best[q[:, 2] > 1e-6] <= JOINT_TOL_RAD)


def test_joint_limits_beyond_pi_shift_representative(tmp_path):
    arm = load_arm(_arm_toml(tmp_path, limits=[(0, 360), None, None, None, None]))
    q = ref.random_joints(arm, 5000, np.random.default_rng(13))      # q1 in [0, 2 pi]
    p, n, o, a = ref.fk(arm, q)
    res = ref.ik(arm, p, a, n, o)
    assert np.all(res.q[..., 0][res.valid] >= 0)
    dq = np.abs(res.q - q[:, None, :]).max(axis=-1)                   # no wrapping needed
    best = np.where(res.valid, dq, np.inf).min(axis=1)
    assert best.max() <= JOINT_TOL_RAD


@pytest.mark.parametrize("override, field", [
    ({1: {"alpha": 90}}, "joint[2].alpha"),
    ({0: {"a": None}}, "joint[1].a"),
    ({2: {"a": '"long"'}}, "joint[3].a"),
    ({2: {"d": 1.0}}, "joint[3].d"),
    ({4: {"a": 2.0}}, "joint[5].a"),
    ({3: {"limits": "[10, -10]"}}, "joint[4].limits"),
    ({3: {"limits": "[10]"}}, "joint[4].limits"),
    ({1: {"bogus": 1}}, "joint[2]"),
])
def test_arm_toml_errors_name_file_and_field(tmp_path, override, field):
    path = _arm_toml(tmp_path, name="bad.toml", override=override)
    with pytest.raises(InputError) as info:
        load_arm(path)
    message = str(info.value)
    assert message.startswith(f"{path}: field '{field}': "), message
    assert info.value.field == field


def test_arm_toml_not_toml_and_missing_file(tmp_path):
    bad = tmp_path / "broken.toml"
    bad.write_text("name = \n")
    with pytest.raises(InputError, match="broken.toml"):
        load_arm(bad)
    with pytest.raises(InputError, match="nothere.toml"):
        load_arm(tmp_path / "nothere.toml")
    units = tmp_path / "units.toml"
    units.write_text(_arm_toml(tmp_path).read_text().replace('length_unit = "cm"', 'length_unit = "ft"'))
    with pytest.raises(InputError, match=r"units\.toml: field 'length_unit'"):
        load_arm(units)
