"""The IR of the traced IK (``ik5r.hdl.graph``): the registry's meaning of every operation, run on
the traced graph, computes what the body computes (``ik5r.core.ik.solve``), bit for bit, on
integers and on numpy arrays; every operation has a spec, a lowering and a unit; the nodes are
frozen and the status events are kept beside them."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ik5r.core import fixedpoint, fixedpoint_np, ik
from ik5r.core.fxconfig import constants, load_config
from ik5r.firmware_model import model, vector, vectors
from ik5r.firmware_model.poses import concat
from ik5r.hdl.graph import registry
from ik5r.hdl.graph.evaluate import evaluate
from ik5r.hdl.graph.nodes import Node
from ik5r.hdl.graph.ops import Op
from ik5r.hdl.graph.trace import trace
from ik5r.hdl.pipelined.glue import UNITS
from ik5r.hdl.sequenced.lower import LOWERING


def _batch(k, seed):
    """Random reachable poses on every branch, the directed set and the edge words."""
    return concat(vectors.random_poses(k, 40, seed), vectors.directed_poses(k), vectors.edge_poses(k))


def _args(b):
    return b.p.T, b.a.T, b.n.T, b.o.T, b.roll, b.back, b.down, b.q5


def _row(b, i):
    return ([int(v) for v in b.p[i]], [int(v) for v in b.a[i]], [int(v) for v in b.n[i]],
            [int(v) for v in b.o[i]], bool(b.roll[i]), bool(b.back[i]), bool(b.down[i]), int(b.q5[i]))


def _differing(t, k, b) -> int:
    """Rows where the graph's joints or status differ from the body's, on numpy arrays."""
    (joints, status), (want, want_status) = (
        evaluate(t, fixedpoint_np, vector.KERNELS, k, *_args(b)),
        ik.solve(fixedpoint_np, vector.KERNELS, k, *_args(b)))
    bad = np.asarray(status) != np.asarray(want_status)
    for got, ref in zip(joints, want):
        bad |= np.asarray(got) != np.asarray(ref)
    return int(bad.sum())


@pytest.mark.parametrize("name", ["q18", "q24", "q32", "q32w"])
def test_the_graph_computes_the_body_on_arrays(name):
    k = constants(load_config(name))
    b = _batch(k, 29)
    assert len(b.p) > 300
    assert _differing(trace(k), k, b) == 0


@pytest.mark.parametrize("name", ["q18", "q32w"])
def test_the_graph_computes_the_body_on_integers(name):
    k = constants(load_config(name))
    t, b = trace(k), _batch(k, 7)
    statuses = set()
    for i in range(0, len(b.p), 7):
        joints, status = evaluate(t, fixedpoint, model.KERNELS, k, *_row(b, i))
        want, want_status = ik.solve(fixedpoint, model.KERNELS, k, *_row(b, i))
        assert (list(joints), status) == (list(want), want_status), i
        statuses.add(status)
    assert len(statuses) > 2             # the rows reach several status bits, not only "ok"


def test_a_wrong_meaning_is_caught(monkeypatch):
    """The comparison can fail: one operation's meaning off by one LSB, or a status leaf lost."""
    k = constants(load_config("q18"))
    b = _batch(k, 3)
    spec = registry.SPECS[Op.WRAP]
    monkeypatch.setitem(registry.SPECS, Op.WRAP, dataclasses.replace(
        spec, meaning=lambda ev, n, a: spec.meaning(ev, n, a) + 1))
    assert _differing(trace(k), k, b) > 0
    monkeypatch.setitem(registry.SPECS, Op.WRAP, spec)
    t = trace(k)
    t.events.leaves = t.events.leaves[1:]
    assert _differing(t, k, b) > 0


def test_every_op_has_a_spec_a_lowering_and_a_unit():
    assert set(registry.SPECS) == set(Op) == set(LOWERING) == set(UNITS)
    partial = {op: None for op in Op if op != Op.SQRT}
    with pytest.raises(NotImplementedError, match="a core: no entry for SQRT"):
        registry.require_every_op(partial, "a core")
    assert registry.require_every_op(partial, "a core", spare=(Op.SQRT,)) is partial


def test_nodes_are_frozen_unique_and_carry_no_status():
    k = constants(load_config("q18"))
    joints, events, g = trace(k)
    n = joints[0]
    with pytest.raises(dataclasses.FrozenInstanceError):
        n.lo = 0
    assert not hasattr(n, "events") and not hasattr(n, "__dict__")
    a, b = [v for v in g.nodes if isinstance(v, Node) and v.op == Op.INPUT][:2]
    assert g.node(Op.ADD, (a, b)) is g.node(Op.ADD, (a, b))
    assert g.node(Op.ADD, (a, b)).bounds() == (a.lo + b.lo, a.hi + b.hi)
    with pytest.raises(TypeError, match="ADD takes 2 arguments"):
        g.node(Op.ADD, (a,))
    # The leaves sit beside the graph, each on the value that decides it.
    carriers = [leaf.carrier for leaf in events]
    assert len(carriers) > 10 and all(c is None or any(c is v for v in g.nodes) for c in carriers)
