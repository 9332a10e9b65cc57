"""Block orders kept from a longer search (:mod:`.search`): ``schedules/<fingerprint>.json``.

A compile whose blocks have the fingerprint of a kept order places them in that order (one list
scheduling, :func:`.schedule.placed`; each block no earlier than its kept start, if the order
was placed by the constraint solver) instead of climbing from the longest-path priorities. Any
order gives a valid program (each block at the first clock its claims are free and its words are
stored); a kept order only decides how short the program is. A change of the lowering, of the
instruction set or of the claims changes the fingerprint: the compile then climbs as before, and
``tests/test_seq_search.py`` names the kept orders no design point uses.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

__all__ = ["SCHEDULES", "fingerprint", "hint", "modulo_hint", "order_files", "schedule_files"]

#: The kept orders, one JSON file per fingerprint.
SCHEDULES = Path(__file__).resolve().parent / "schedules"


def fingerprint(blocks) -> str:
    """16 hex digits of SHA-256 over what the placer sees of ``blocks``
    (:func:`.schedule.blocks_of`): each block's code (folded, hazards padded), its claims and
    conditions per clock, and the order constraints."""
    h = hashlib.sha256()
    for b in blocks:
        h.update(repr((b.code, [sorted(keys) for keys in b.claims], b.conds)).encode())
    h.update(repr(sorted(getattr(blocks, "after", {}).items())).encode())
    return h.hexdigest()[:16]


def hint(blocks) -> tuple[list, list | None] | None:
    """The kept order of ``blocks`` (one priority per block) and its earliest starts (one clock
    per block, kept by the constraint solver's search, :mod:`.cpsat`; else None), or None."""
    path = SCHEDULES / f"{fingerprint(blocks)}.json"
    if not path.is_file():
        return None
    kept = json.loads(path.read_text())
    priorities, starts = kept["priorities"], kept.get("starts")
    for name, values in (("priorities", priorities), ("starts", starts or blocks)):
        if len(values) != len(blocks):
            raise ValueError(f"{path}: {len(values)} {name} for {len(blocks)} blocks")
    return priorities, starts


def modulo_hint(blocks) -> tuple[int, list] | None:
    """The kept modulo schedule of a two-pose program's ``blocks`` (:mod:`.modulo`): (the
    template's period, its blocks' starts), or None."""
    path = SCHEDULES / "modulo" / f"{fingerprint(blocks)}.json"
    if not path.is_file():
        return None
    kept = json.loads(path.read_text())
    return kept["period"], kept["starts"]


def order_files() -> list[Path]:
    """The kept orders' files."""
    return sorted(SCHEDULES.glob("*.json"))


def schedule_files() -> list[Path]:
    """The kept orders' and modulo schedules' files (data the programs, hence the Verilog,
    depend on: cache keys)."""
    return order_files() + sorted(SCHEDULES.glob("modulo/*.json"))
