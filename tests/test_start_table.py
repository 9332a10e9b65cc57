"""The start table of the numeric solver (ik5r.numeric.start_table): cells, modes, and that its starts help."""

import numpy as np
import pytest

from ik5r.core.chain import fk, load_chain, random_joints, shipped_arm
from ik5r.numeric import lmkernel, multistart
from ik5r.numeric import solver as nm
from ik5r.numeric.start_table import StartTable, table_for


def _targets(mode, R, p):
    return nm.Targets(mode, p, R if mode == "pose" else None, R[:, :, 2] if mode == "direction" else None)


@pytest.mark.parametrize("mode", nm.MODES)
def test_each_start_lands_in_its_targets_cell(mode):
    chain = load_chain(shipped_arm("puma560"))
    R, p = fk(chain, random_joints(chain, 400, np.random.default_rng(5)))
    table = StartTable(chain, mode)
    q, found = table.lookup(_targets(mode, R, p))
    assert np.isfinite(q[found, 1]).mean() > 0.8  # most cells hold a second entry
    q = q[:, 0]
    assert found.mean() > 0.9
    assert np.isnan(q[~found]).all() and np.isfinite(q[found]).all()
    R2, p2 = fk(chain, q[found])
    assert np.array_equal(table._keys(p2, R2, R2[:, :, 2]), table._keys(p[found], R[found], R[found][:, :, 2]))


def test_table_is_cached_per_arm_and_mode_and_checks_the_mode():
    puma, toz = load_chain(shipped_arm("puma560")), load_chain(shipped_arm("toz-6r"))
    assert table_for(puma, "pose") is table_for(load_chain(shipped_arm("puma560")), "pose")
    assert table_for(puma, "pose") is not table_for(puma, "position")
    assert table_for(puma, "pose") is not table_for(toz, "pose")
    with pytest.raises(ValueError, match="mode"):
        table_for(puma, "pose").lookup(nm.Targets("position", np.zeros((1, 3))))


@pytest.mark.skipif(not lmkernel.available(), reason="no C compiler")
@pytest.mark.parametrize("name", ["puma560", "toz-6r"])
def test_table_starts_converge_more_often_in_fewer_steps(name):
    chain = load_chain(shipped_arm(name))
    rng = np.random.default_rng(11)
    R, p = fk(chain, random_joints(chain, 2000, rng))
    targets = nm.Targets("pose", p, R)
    rows = np.arange(len(p))
    uniform_q = random_joints(chain, len(p), rng)
    table_q = multistart._table_starts(chain, targets, rows)[:, 0]
    table_q = np.where(np.isnan(table_q), uniform_q, table_q)  # an empty cell: a uniform start, as solve does
    *_, conv_t, _, steps_t = lmkernel.levenberg_marquardt(chain, targets, table_q, rows=rows, return_iterations=True,
                                                          damping=multistart.TABLE_DAMPING)
    *_, conv_u, _, steps_u = lmkernel.levenberg_marquardt(chain, targets, uniform_q, rows=rows, return_iterations=True)
    assert conv_t.mean() > conv_u.mean() + 0.03
    assert steps_t.mean() < steps_u.mean() - 1.0


def test_quaternion_matches_scipy():
    from scipy.spatial.transform import Rotation

    from ik5r.numeric.start_table import _quaternion

    rot = Rotation.random(500, random_state=3)
    want = np.roll(rot.as_quat(), 1, axis=1)  # scipy: x, y, z, w
    want *= np.where(want[:, :1] < 0, -1.0, 1.0)
    assert np.allclose(_quaternion(rot.as_matrix()), want, atol=1e-12)


def test_table_is_stored_on_disk_and_loads_the_same_numbers(tmp_path, monkeypatch):
    from ik5r.numeric import start_table

    monkeypatch.setenv("IK5R_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(start_table, "_CACHE", {})
    chain = load_chain(shipped_arm("puma560"))
    built = start_table.table_for(chain, "direction")
    stored = list(tmp_path.glob("start-table-*.npz"))
    assert len(stored) == 1
    monkeypatch.setattr(start_table, "_CACHE", {})
    loaded = start_table.table_for(chain, "direction")
    assert loaded is not built
    for name in start_table._STORED:
        assert np.array_equal(getattr(loaded, name), getattr(built, name), equal_nan=True)
    R, p = fk(chain, random_joints(chain, 50, np.random.default_rng(2)))
    targets = _targets("direction", R, p)
    assert np.array_equal(loaded.lookup(targets)[0], built.lookup(targets)[0], equal_nan=True)
    stored[0].write_bytes(b"not a table")  # a damaged file is rebuilt, not trusted
    monkeypatch.setattr(start_table, "_CACHE", {})
    assert np.array_equal(start_table.table_for(chain, "direction").q, built.q, equal_nan=True)
