"""The testbench's word-level port map of the word-serial wrapper (``serial.word_portmap``): the
compact core's port map with the wrapper's module and timing, derived from the payload fields
without building the core (building it compiles its program: the schedule search)."""

from __future__ import annotations

import pytest

from ik5r.core.arm import load_arm
from ik5r.core.fxconfig import Constants, load_config


def _silenced(component):
    for c in (component, component._engine):
        c._MustUse__silence = True          # built for its port map only, never elaborated
    return component


@pytest.mark.parametrize("arm", ["hu-5r", "scorbot-er4u"])
def test_word_portmap_is_the_compact_cores_without_building_it(arm, monkeypatch):
    from ik5r.hdl.generate import build, portmap
    from ik5r.hdl.sequenced import program
    from ik5r.tools.testbench.serial import word_portmap

    k = Constants(load_config("q32w"), load_arm(arm))
    beat_map = portmap(_silenced(build("ik", "compact", k, 8, serial=16)), "ik", "compact", k)
    core_map = portmap(_silenced(build("ik", "compact", k, 8)), "ik", "compact", k)

    # No program is compiled for it (the compiled one is cached per process: hide it).
    def no_compile(_):
        raise AssertionError("word_portmap compiled the core's program")

    monkeypatch.setattr(program, "_compile", no_compile)
    words = word_portmap(beat_map, k, 8)

    want = dict(core_map, module=beat_map["module"], latency_cycles=beat_map["latency_cycles"],
                cycles_per_result=beat_map["cycles_per_result"], serial={"beat_bits": 16})
    assert words == want
    status = next(f for f in words["streams"]["o"]["fields"] if f["name"] == "status")
    assert status["width"] == k.status_width
