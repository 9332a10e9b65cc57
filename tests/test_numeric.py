"""Any serial arm (ik5r.core.chain) and its numeric IK (ik5r.numeric.solver, ik5r.numeric.multistart), CLI included."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from ik5r.core import reference
from ik5r.core.arm import load_arm
from ik5r.core.chain import fk, jacobian, load_chain, parse_chain, random_joints, shipped_arm
from ik5r.numeric import multistart
from ik5r.numeric import solver as nm
from ik5r.tools.cli import main

ARMS = ("hu-5r", "toz-6r", "park-5r", "patil-5r", "puma560")
#: Toz, Table 2: P1..P5 (cm).
TOZ_TARGETS = np.array([[21.1736, -57.2067, 276.4353], [1.0086, -63.1067, 303.8828],
                        [-48.0754, -119.2732, 229.7840], [8.8484, -178.875, 264.7266],
                        [40.1814, 21.4357, 299.5422]])

PRISMATIC_ARM = """
convention = "modified"
length_unit = "mm"
[[joint]]
a = 0
alpha = 0
d = 100
[[joint]]
type = "prismatic"
a = 50
alpha = -90
theta_offset = 30
d = 20
limits = [0, 300]
[[joint]]
a = 10
alpha = 90
d = 40
scale = -1
limits = [-150, 150]
[tool]
xyz = [5, 10, 60]
rpy = [10, 20, 30]
"""


def _read(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _write(path, names, rows):
    path.write_text(",".join(names) + "\n" + "".join(",".join(repr(float(v)) for v in r) + "\n" for r in rows))
    return path


def test_general_chain_matches_the_5r_reference():
    chain, arm = load_chain(), load_arm()
    q = np.random.default_rng(1).uniform(-3, 3, (500, 5))
    R, p = fk(chain, q)
    pr, n, o, a = reference.fk(arm, q)
    assert np.abs(p - pr).max() < 1e-12
    assert np.abs(R - np.stack([n, o, a], axis=2)).max() < 1e-14


@pytest.mark.parametrize("name", ARMS + ("prismatic",))
def test_jacobian_is_the_derivative_of_fk(name, tmp_path):
    if name == "prismatic":
        chain = parse_chain(__import__("tomllib").loads(PRISMATIC_ARM), "prismatic.toml")
    else:
        chain = load_chain(shipped_arm(name))
    q = random_joints(chain, 4, np.random.default_rng(2))
    R, p, J = jacobian(chain, q)
    h = 1e-6
    for j in range(chain.n):
        dq = np.zeros(chain.n)
        dq[j] = h
        (Rp, pp), (Rm, pm) = fk(chain, q + dq), fk(chain, q - dq)
        assert np.abs((pp - pm) / (2 * h) - J[:, :3, j]).max() < 1e-6 * chain.reach
        # angular velocity: dR/dq = [w]x R, so w = vee(dR R^T)
        W = ((Rp - Rm) / (2 * h)) @ np.swapaxes(R, 1, 2)
        w = np.stack([W[:, 2, 1], W[:, 0, 2], W[:, 1, 0]], axis=1)
        assert np.abs(w - J[:, 3:, j]).max() < 1e-6


def test_seed_arms_reproduce_their_papers():
    # Patil: all joints 0 is the home point (58, 0, 0) cm.
    _, p = fk(load_chain(shipped_arm("patil-5r")), np.zeros((1, 5)))
    assert np.abs(p[0] - [58, 0, 0]).max() < 1e-12
    # Park: the rotation at the start of the welding move (psi, assumed, does not change it).
    R, p = fk(load_chain(shipped_arm("park-5r")), np.radians([[-45, 30, 30, 90, -90]]))
    paper = np.array([[-0.707, -0.354, -0.612], [-0.707, 0.354, 0.612], [0, 0.866, -0.5]])
    assert np.abs(R[0] - paper).max() < 0.001
    # Toz, all joints 0, the product of Eq. (2)'s matrices by hand: x = l4 + l5, y = -l2,
    # z = l1 + l3 + l6.
    _, p = fk(load_chain(shipped_arm("toz-6r")), np.zeros((1, 6)))
    assert np.abs(p[0] - [100, -120, 290]).max() < 1e-12


def test_toz_table2_targets_cli(tmp_path):
    poses = _write(tmp_path / "toz.csv", ["px", "py", "pz"], TOZ_TARGETS)
    out = tmp_path / "q.csv"
    assert main(["solve", str(poses), "--solver", "numeric", "--arm", str(shipped_arm("toz-6r")),
                 "--mode", "position", "-o", str(out)]) == 0
    rows = _read(out)
    assert [r["status"] for r in rows] == ["ok"] * 5
    q = np.array([[float(r[f"q{j + 1}"]) for j in range(6)] for r in rows])
    _, p = fk(load_chain(shipped_arm("toz-6r")), q)
    assert np.linalg.norm(p - TOZ_TARGETS, axis=1).max() <= 1e-9
    assert max(float(r["pos_err_cm"]) for r in rows) <= 1e-9


def _same(qa, qb):
    return np.abs(reference.wrap(qa - qb)).max() < 1e-7


def test_numeric_agrees_with_the_closed_form_on_the_5r():
    arm, chain = load_arm(), load_chain()
    rng = np.random.default_rng(3)
    q = reference.random_joints(arm, 40, rng)
    p, n, o, a = reference.fk(arm, q)
    closed = reference.ik(arm, p, a, n, o)
    sol = multistart.solve(chain, nm.Targets("pose", p, np.stack([n, o, a], axis=2)), all_solutions=True, starts=48)
    for i in range(len(q)):
        mine = sol.q[(sol.row == i) & (sol.status == nm.OK)]
        theirs = closed.q[i][closed.valid[i]]
        assert len(theirs) >= 1
        assert len(mine) == len(theirs), i
        for qc in theirs:
            assert any(_same(qc, qn) for qn in mine), (i, qc, mine)


@pytest.mark.parametrize("all_solutions", [False, True])
def test_answers_do_not_depend_on_the_rest_of_the_batch(all_solutions):
    """A pose's starts come from its own numbers and the seed: solved alone, among others, or
    elsewhere in the batch, it gets the same rows; another seed gives other starts."""
    chain = load_chain(shipped_arm("toz-6r"))
    R, p = fk(chain, random_joints(chain, 24, np.random.default_rng(11)))
    targets = nm.Targets("pose", p, R)
    kw = {"all_solutions": all_solutions, "starts": 12 if all_solutions else None}
    whole = multistart.solve(chain, targets, **kw)
    order = np.arange(len(p))[::-1]
    for part in (np.array([5]), order, np.arange(3, 17)):
        alone = multistart.solve(chain, targets.take(part), **kw)
        for j, i in enumerate(part):
            assert np.array_equal(alone.q[alone.row == j], whole.q[whole.row == i])
            assert np.array_equal(alone.status[alone.row == j], whole.status[whole.row == i])
    keys = multistart.pose_keys(targets, 0)
    assert len(np.unique(keys)) == len(p) and not np.array_equal(keys, multistart.pose_keys(targets, 1))


def test_puma_all_finds_eight_solutions():
    chain = load_chain(shipped_arm("puma560"))
    q = random_joints(chain, 12, np.random.default_rng(4))
    R, p = fk(chain, q)
    sol = multistart.solve(chain, nm.Targets("pose", p, R), all_solutions=True)
    counts = sol.counts(len(q))
    assert (counts == 8).sum() >= 11, counts  # a PUMA 560 pose has at most 8
    assert (counts <= 8).all()
    ok = sol.status == nm.OK
    R2, p2 = fk(chain, sol.q[ok])
    assert np.linalg.norm(p2 - p[sol.row[ok]], axis=1).max() <= 1e-9
    assert np.abs(R2 - R[sol.row[ok]]).max() <= 1e-9
    for i in range(len(q)):  # the joints the pose came from are among them
        assert any(_same(q[i], s) for s in sol.q[ok & (sol.row == i)])


def test_direction_mode_leaves_the_roll_free():
    chain = load_chain(shipped_arm("park-5r"))
    q = random_joints(chain, 30, np.random.default_rng(5))
    R, p = fk(chain, q)
    sol = multistart.solve(chain, nm.Targets("direction", p, a=R[:, :, 2]))
    assert (sol.status == nm.OK).all()
    R2, p2 = fk(chain, sol.q)
    assert np.linalg.norm(p2 - p, axis=1).max() <= 1e-9
    assert np.linalg.norm(R2[:, :, 2] - R[:, :, 2], axis=1).max() <= 1e-9


def test_statuses_unreachable_invalid_not_converged():
    chain = load_chain(shipped_arm("puma560"))
    R, p = fk(chain, random_joints(chain, 4, np.random.default_rng(6)))
    p[0] = [500.0, 0, 0]  # beyond the reach bound
    p[1, 0] = math.nan
    R[2] = R[2] * 1.01  # not a rotation
    sol = multistart.solve(chain, nm.Targets("pose", p, R), starts=4)
    assert list(sol.status) == [nm.UNREACHABLE, nm.INVALID, nm.INVALID, nm.OK]
    # Reachable by the geometry, not within narrow limits: no start converges, honest status.
    narrow = parse_chain({"joint": [{"a": 10, "alpha": 0, "limits": [0, 10]},
                                    {"a": 10, "alpha": 0, "limits": [0, 10]}]}, "narrow.toml")
    sol = multistart.solve(narrow, nm.Targets("position", np.array([[0.0, 15.0, 0.0]])), starts=8)
    assert sol.status[0] in (nm.NOT_CONVERGED, nm.SINGULAR) and sol.pos_err[0] > 1.0


def test_prismatic_arm_solved_in_position_mode():
    chain = parse_chain(__import__("tomllib").loads(PRISMATIC_ARM), "prismatic.toml")
    q = random_joints(chain, 40, np.random.default_rng(8))
    _, p = fk(chain, q)
    sol = multistart.solve(chain, nm.Targets("position", p))
    assert (sol.status == nm.OK).all()
    assert ((sol.q >= chain.lower - 1e-12) & (sol.q <= chain.upper + 1e-12)).all()  # within the limits
    _, p2 = fk(chain, sol.q)
    assert np.linalg.norm(p2 - p, axis=1).max() <= 1e-9


def test_fk_cli_any_arm(tmp_path):
    joints = _write(tmp_path / "q.csv", [f"q{j + 1}" for j in range(6)], [[0.1, 0.2, 0.3, 0.4, 0.5, 0.6]])
    out = tmp_path / "p.csv"
    assert main(["fk", str(joints), "--arm", str(shipped_arm("puma560")), "-o", str(out)]) == 0
    row = _read(out)[0]
    R, p = fk(load_chain(shipped_arm("puma560")), np.array([[0.1, 0.2, 0.3, 0.4, 0.5, 0.6]]))
    assert float(row["px"]) == p[0, 0] and float(row["az"]) == R[0, 2, 2]


BAD_ARMS = [
    ("", "joint"),
    ("".join("[[joint]]\na = 1\nalpha = 0\n" for _ in range(8)), "joint"),
    ('[[joint]]\na = "x"\nalpha = 0\n', "joint[1].a"),
    ("[[joint]]\na = inf\nalpha = 0\n", "joint[1].a"),
    ("[[joint]]\na = 1\nalpha = nan\n", "joint[1].alpha"),
    ('convention = "craig"\n[[joint]]\na = 1\nalpha = 0\n', "convention"),
    ('[[joint]]\ntype = "helical"\na = 1\nalpha = 0\n', "joint[1].type"),
    ('[[joint]]\ntype = "prismatic"\na = 1\nalpha = 0\n', "joint[1].limits"),
    ("[[joint]]\na = 1\nalpha = 0\n[tool]\nxyz = [1, 2]\n", "tool.xyz"),
]


@pytest.mark.parametrize("text,field", BAD_ARMS)
def test_bad_arm_file_exit_2_with_file_and_field(text, field, tmp_path, capsys):
    arm = tmp_path / "bad.toml"
    arm.write_text(text)
    poses = _write(tmp_path / "p.csv", ["px", "py", "pz"], [[1, 2, 3]])
    for argv in (["solve", str(poses), "--solver", "numeric", "--mode", "position"], ["fk", str(poses)]):
        assert main([*argv, "--arm", str(arm)]) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith(f"{arm}:") and f"field '{field}'" in err and "\n" not in err


@pytest.mark.parametrize("mode,names,line", [("pose", ["px", "py", "pz", "ax", "ay", "az"], 1),
                                             ("direction", ["px", "py", "pz"], 1),
                                             ("position", ["px", "py"], 1)])
def test_poses_missing_columns_exit_2_file_line(mode, names, line, tmp_path, capsys):
    poses = _write(tmp_path / "p.csv", names, [[1.0] * len(names)])
    assert main(["solve", str(poses), "--solver", "numeric", "--mode", mode,
                 "--arm", str(shipped_arm("toz-6r"))]) == 2
    assert capsys.readouterr().err.startswith(f"{poses}:{line}: field ")


def test_poses_ragged_record_exit_2_file_line(tmp_path, capsys):
    poses = tmp_path / "p.csv"
    poses.write_text("px,py,pz\n1,2,3\n4,5\n")
    assert main(["solve", str(poses), "--solver", "numeric", "--mode", "position",
                 "--arm", str(shipped_arm("toz-6r"))]) == 2
    assert capsys.readouterr().err.startswith(f"{poses}:3: ")


def test_poses_on_error_skip_numeric(tmp_path, capsys):
    """--on-error skip: the bad record reported as FILE:LINE, the others solved under their own
    row numbers (those of a run without the bad record), exit 3."""
    arm = str(shipped_arm("toz-6r"))
    q = random_joints(load_chain(arm), 3, np.random.default_rng(4))
    points = fk(load_chain(arm), q)[1]
    rows = [",".join(repr(float(v)) for v in point) for point in points]
    poses = tmp_path / "p.csv"
    poses.write_text("\n".join(["px,py,pz", rows[0], "4,5", rows[1], rows[2]]) + "\n")
    out = tmp_path / "o.csv"
    argv = ["solve", str(poses), "--solver", "numeric", "--mode", "position", "--arm", arm, "-o", str(out)]
    assert main(argv + ["--on-error", "skip"]) == 3
    assert capsys.readouterr().err.startswith(f"{poses}:3: expected 3 fields, got 2")
    got = _read(out)
    assert [int(r["row"]) for r in got] == [0, 2, 3]
    assert all(r["status"] == "ok" for r in got)
    assert main(argv) == 2 and not out.exists()


def test_solver_default_is_closed_form_for_the_5r_and_numeric_otherwise(tmp_path):
    arm = load_arm()
    p, n, o, a = reference.fk(arm, reference.random_joints(arm, 3, np.random.default_rng(7)))
    names = ["px", "py", "pz", "nx", "ny", "nz", "ox", "oy", "oz", "ax", "ay", "az"]
    poses = _write(tmp_path / "p.csv", names, np.concatenate([p, n, o, a], axis=1))
    out = tmp_path / "q.csv"
    assert main(["solve", str(poses), "-o", str(out), "--arm", str(shipped_arm("hu-5r"))]) == 0
    assert "branch" in _read(out)[0]
    assert main(["solve", str(poses), "-o", str(out), "--arm", str(shipped_arm("patil-5r"))]) == 0
    assert "solution" in _read(out)[0]
