"""The numeric solver on arms nobody tuned it for (issue 26, item 7): with the default options,
a pose still unsolved after the default 32 starts gets more (up to 128), and the poses solved
earlier get exactly the answer they had. Random 6R arms of both DH conventions, drawn here."""

from __future__ import annotations

import time

import numpy as np
import pytest

from ik5r.core.chain import fk, load_chain, parse_chain, random_joints, shipped_arm
from ik5r.numeric import multistart
from ik5r.numeric import solver as nm


def _random_6r(rng, convention: str):
    joints = [{"a": float(rng.uniform(0, 40)), "alpha": float(rng.choice([-90, 90, 0, 60, -45])),
               "d": float(rng.uniform(-20, 40)), "theta_offset": float(rng.uniform(-180, 180))}
              for _ in range(6)]
    joints[1]["a"] = float(rng.uniform(20, 50))    # a real upper arm
    return parse_chain({"name": f"random-{convention}", "convention": convention, "joint": joints}, "<random>")


def _solved_share(chain, poses: int, seed: int):
    q = random_joints(chain, poses, np.random.default_rng(seed))
    R, p = fk(chain, q)
    t0 = time.perf_counter()
    sol = multistart.solve(chain, nm.Targets("pose", p, R))
    seconds = time.perf_counter() - t0
    ok = (sol.status == nm.OK) & (sol.pos_err <= 1e-9) & (sol.rot_err <= 1e-9)
    return ok.mean(), seconds / poses, sol


@pytest.mark.parametrize("convention", ["standard", "modified"])
def test_random_6r_arms_solved_with_default_options(convention, capsys):
    rng = np.random.default_rng({"standard": 61, "modified": 62}[convention])
    for _ in range(2):
        chain = _random_6r(rng, convention)
        share, per_pose, _ = _solved_share(chain, 1000, 5)
        with capsys.disabled():
            print(f"\n{chain.name}: {share:.2%} of 1000 random reachable poses solved, {per_pose * 1e3:.2f} ms/pose")
        assert share >= 0.999


@pytest.mark.parametrize("arm", ["puma560", "toz-6r"])
def test_shipped_6r_arms_solved_with_default_options(arm, capsys):
    share, per_pose, _ = _solved_share(load_chain(shipped_arm(arm)), 1000, 6)
    with capsys.disabled():
        print(f"\n{arm}: {share:.2%} solved, {per_pose * 1e3:.2f} ms/pose")
    assert share >= 0.999


def test_escalation_changes_only_the_poses_unsolved_after_the_first_starts():
    """With few starts and no start table many poses stay unsolved: escalating (2 starts, then up
    to 16) solves more of them, and every pose solved within the first 2 keeps its answer, bit
    for bit (the same starts in the same order)."""
    chain = load_chain(shipped_arm("toz-6r"))
    q = random_joints(chain, 200, np.random.default_rng(7))
    R, p = fk(chain, q)
    targets = nm.Targets("pose", p, R)
    first = multistart.solve_first(chain, targets, 2, table=False)
    more = multistart.solve_first(chain, targets, 2, table=False, escalate=16)
    early = first.status == nm.OK
    assert 0 < early.sum() < len(early)        # the case exercises both kinds of pose
    np.testing.assert_array_equal(more.q[early], first.q[early])
    assert (more.status == nm.OK).sum() > early.sum()
