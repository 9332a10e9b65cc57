"""Make ``ik5r.hdl.tb`` importable without (or before) ``hdl/__init__.py``.

``ensure()`` imports the real ``ik5r.hdl`` package and falls back to a bare namespace module when it
cannot be imported. ``ensure(light=True)`` (the simulator's Python, where only the testbench is
needed) registers the bare namespace module without running ``hdl/__init__.py``, which imports
Amaranth: seconds of start-up saved on every simulation.
"""

from __future__ import annotations

import sys
import types
from pathlib import Path

HDL_DIR = Path(__file__).resolve().parents[1]


def _bare() -> None:
    import ik5r

    module = types.ModuleType("ik5r.hdl")
    module.__path__ = [str(HDL_DIR)]
    module.__file__ = None
    sys.modules["ik5r.hdl"] = module
    ik5r.hdl = module


def ensure(light: bool = False) -> None:
    if "ik5r.hdl" in sys.modules:
        return
    if light:
        _bare()
        return
    try:
        import ik5r.hdl  # noqa: F401
    except ModuleNotFoundError as exc:
        if exc.name != "ik5r.hdl":
            raise
        _bare()
