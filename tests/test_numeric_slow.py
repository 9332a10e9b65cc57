"""Issue 17's accuracy floors on large random runs (``make test-slow``); speed lives in ``make bench``."""

from __future__ import annotations

import numpy as np
import pytest

from ik5r.core.chain import fk, load_chain, random_joints, shipped_arm
from ik5r.numeric import multistart
from ik5r.numeric import solver as nm

pytestmark = pytest.mark.slow


@pytest.mark.parametrize("name", ["toz-6r", "puma560"])
def test_random_reachable_poses_solved_to_1e9(name):
    chain = load_chain(shipped_arm(name))
    R, p = fk(chain, random_joints(chain, 10_000, np.random.default_rng(11)))
    sol = multistart.solve(chain, nm.Targets("pose", p, R))
    R2, p2 = fk(chain, sol.q)
    pos, rot = nm.residuals(nm.Targets("pose", p, R), R2, p2)
    solved = (pos <= 1e-9) & (rot <= 1e-9)
    print(f"{name}: {solved.mean():.4%} of 10,000 poses within 1e-9 cm and 1e-9 rad")
    assert solved.mean() >= 0.999
    assert ((sol.status == nm.OK) == solved).all()  # the status tells the truth


def test_puma_all_eight_for_99_percent():
    chain = load_chain(shipped_arm("puma560"))
    q = random_joints(chain, 1000, np.random.default_rng(12))
    R, p = fk(chain, q)
    sol = multistart.solve(chain, nm.Targets("pose", p, R), all_solutions=True)
    counts = sol.counts(len(q))
    print(f"PUMA 560: solutions per pose {np.bincount(counts).tolist()}")
    assert counts.max() <= 8
    assert np.mean(counts == 8) >= 0.99
