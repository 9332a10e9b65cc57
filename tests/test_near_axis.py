"""The tool point near the base axis (issue 31): reachable poses (FK) with the tool point within
1e-6 cm of the axis, at several approach tilts (``firmware_model.vectors.near_axis_poses``).

There the arm's plane comes from the approach (docs/algorithm.md, "Joint 1 near the base axis"):
every layer gives the same bits, no such pose is called ``bad_orientation``, and the solved tool
direction (approach, n, o) is within 1e-6 rad of the target on every branch that solves. Before
the plane took the approach into account these poses came back up to 1e-3 rad off, or
``bad_orientation``.
"""

from __future__ import annotations

import numpy as np
import pytest

from ik5r.core import reference
from ik5r.core import status as st
from ik5r.core.fxconfig import constants, load_config
from ik5r.core.status_cases import near_axis_joints
from ik5r.firmware_model import csolver, model, vector
from ik5r.firmware_model.vectors import near_axis_poses

FLOOR_RAD = 1e-6


def _angle(u, v):
    return np.arctan2(np.linalg.norm(np.cross(u, v), axis=-1), np.sum(u * v, axis=-1))


@pytest.mark.parametrize("name", ["q32w", "q32"])
def test_near_axis_direction_every_layer(name):
    k = constants(load_config(name))
    poses = near_axis_poses(k)
    got = {"c": poses.solve(lambda *a: csolver.solve_batch(k, *a)),
           "vector": poses.solve(lambda *a: vector.solve_batch(k, *a)),
           "model": poses.solve(lambda *a: model.solve_batch(k, *a))}
    q_a, status = (np.asarray(v) for v in got["c"])
    for layer in ("vector", "model"):
        assert np.array_equal(np.asarray(got[layer][0]), q_a), layer
        assert np.array_equal(np.asarray(got[layer][1]), status), layer
    assert not np.any(status & st.BAD_ORIENTATION)
    solved = (status & (st.UNREACHABLE | st.INVALID)) == 0
    # Each pose solves on its own shoulder (both elbows): at least half the rows.
    assert solved.sum() >= len(status) // 2

    p, n, o, a = (np.repeat(v, 8, axis=0) for v in reference.fk(k.arm, near_axis_joints(k.arm)))
    p_fk, n_fk, o_fk, a_fk = reference.fk(k.arm, q_a * 2.0 ** -k.cfg.frac_angle)
    approach = _angle(a_fk, a)[solved]
    roll = np.asarray(poses.roll) & solved
    no = np.maximum(_angle(n_fk, n), _angle(o_fk, o))[roll]
    assert approach.max() <= FLOOR_RAD, approach.max()
    assert no.max() <= FLOOR_RAD, no.max()
    assert np.linalg.norm(p_fk - p, axis=-1)[solved].max() <= 2.0 ** (2 - k.cfg.frac_length)
