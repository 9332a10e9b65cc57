"""The typed inputs and result of a word-length sweep (:func:`ik5r.tools.sweep.run_sweep`):
what it covers (:class:`SweepOptions`) and what it found (:class:`SweepRecord`), which is written
to and read from ``sweep.json`` here and nowhere else (``ik5r sweep``, ``python -m
ik5r.tools.results`` and the tests all go through :meth:`SweepRecord.write` / :meth:`read`). The
JSON keys are those the records in docs/results were written with: ``{"meta": ..., "points":
[...]}``, each point the flat dict of :func:`ik5r.tools.sweep._point`.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

from ik5r.core.modes import Arch, Block

from .synth import DEFAULT_CACHE, SynthOptions

DEFAULT_WIDTHS = (16, 18, 20, 24, 28, 32)
DEFAULT_POSES = 100_000
#: The file of a sweep's record in its output folder.
RECORD_FILE = "sweep.json"


@dataclass(frozen=True)
class SweepOptions:
    """The points of a sweep: word widths x iteration counts x internal guard bits (None: the
    rule's), each with ``blocks`` x ``archs`` synthesised unless ``synth`` is off; the error
    figures of ``poses`` random poses (``seed``); synthesis by ``synth_options`` (default: the
    defaults of :class:`~ik5r.tools.synth.SynthOptions`), cached under ``synth_cache``, each run
    stopped after ``timeout`` seconds (None: never)."""

    widths: tuple[int, ...] = DEFAULT_WIDTHS
    iterations: tuple[int, ...] | None = None
    guard_bits: tuple[int, ...] | None = None
    blocks: tuple[str, ...] = (Block.ATAN2,)
    archs: tuple[str, ...] = (Arch.PIPELINED,)
    synth: bool = True
    poses: int = DEFAULT_POSES
    seed: int = 0
    synth_options: SynthOptions = field(default_factory=SynthOptions)
    synth_cache: str = str(DEFAULT_CACHE)
    timeout: float | None = None

    def __post_init__(self):
        # Any iterable (a range, a list) becomes a tuple: the options are hashable and compare.
        for name in ("widths", "iterations", "guard_bits", "blocks", "archs"):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, tuple(value))


@dataclass(frozen=True)
class SweepRecord:
    """What a sweep found: ``meta`` (the rule, the arm, what ran, the failures, timing) and one
    flat dict per point, in sweep order."""

    meta: dict
    points: tuple[dict, ...]

    @property
    def failures(self) -> list:
        return self.meta["failures"]

    def to_json(self) -> str:
        from .report.html import jsonable

        doc = jsonable({"meta": self.meta, "points": list(self.points)})
        return json.dumps(doc, indent=2, allow_nan=False) + "\n"

    def write(self, out_dir: str | Path) -> Path:
        path = Path(out_dir) / RECORD_FILE
        path.write_text(self.to_json())
        return path

    @classmethod
    def read(cls, path: str | Path) -> "SweepRecord":
        """The record of ``path`` (a ``sweep.json``, or the folder holding one)."""
        path = Path(path)
        doc = json.loads((path / RECORD_FILE if path.is_dir() else path).read_text())
        return cls(doc["meta"], tuple(doc["points"]))
