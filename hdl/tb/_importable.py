"""Make ``ik5r.hdl.tb`` importable even while ``hdl/`` has no ``__init__.py`` (namespace fallback)."""

from __future__ import annotations

import sys
import types
from pathlib import Path

HDL_DIR = Path(__file__).resolve().parents[1]


def ensure() -> None:
    try:
        import ik5r.hdl  # noqa: F401
        return
    except ModuleNotFoundError:
        pass
    import ik5r

    module = types.ModuleType("ik5r.hdl")
    module.__path__ = [str(HDL_DIR)]
    sys.modules["ik5r.hdl"] = module
    ik5r.hdl = module
