"""The job of one testbench run and its results: what to simulate, the stimulus with its expected
values (the bit-accurate model), and the counts written to the result JSON.

The job JSON (path in ``IK5R_TB_JOB``) names the port map, block, config, seed, what to run, and
where to write the result JSON. For the word-serial wrapper of the compact IK core its ``serial``
entry names the beat width; the port map is then the core's word-level one (the fields the beats
carry, see :mod:`.serial`).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from ik5r.core.arm import Arm, load_arm
from ik5r.core.fxconfig import Constants, load_config, parse_config

from .blocks import get_block
from .portmap import load_portmap


def _config(d: dict):
    """The job's config: its TOML text (the runner writes it), else its name or file."""
    if d.get("config_toml"):
        import tomllib
        return parse_config(tomllib.loads(d["config_toml"]), f"<job config {d.get('config')}>")
    return load_config(d.get("config"))


def _arm(fields: dict | None) -> Arm | None:
    """The job's arm (the fields of :class:`~ik5r.core.arm.Arm`), None: the arm of record."""
    if fields is None:
        return None
    tuples = {k: tuple(tuple(x) if isinstance(x, list) else x for x in v) if isinstance(v, list) else v
              for k, v in fields.items()}
    return Arm(**tuples)


class Job:
    def __init__(self, path: str | None = None):
        path = path or os.environ["IK5R_TB_JOB"]
        self.doc = json.loads(Path(path).read_text())
        d = self.doc
        self.pm = load_portmap(d["portmap"])
        self.spec = get_block(d["block"])
        self.k = Constants(_config(d), _arm(d.get("arm")) or load_arm())
        self.seed = int(d.get("seed", 1))
        self.work = Path(d["work_dir"])
        self.bind_in, self.bind_out = self.spec.bind(self.pm)
        self.tag = self.pm.tag_field
        self.tag_mod = 1 << self.pm.o.fields[self.tag].width if self.tag else None
        self.serial = d.get("serial")        # {"beat_bits": b} for the word-serial wrapper, else None

    def edge_items(self, stride: int = 1, rest: bool = False) -> dict[str, np.ndarray]:
        """The edge set by role: every ``stride``-th item (0, stride, ...), or with ``rest`` the
        others (what a run with that stride left out)."""
        edges = self.spec.edge_inputs(self.pm, self.k)
        n = len(next(iter(edges.values())))
        keep = (np.arange(n) % stride != 0) if rest else (np.arange(n) % stride == 0)
        return {r: v[keep] for r, v in edges.items()}

    def inputs(self, count: int, salt: int, edges: bool = True, edge_stride: int = 1,
               edge_rest: bool = False) -> dict[str, np.ndarray]:
        """Edge set (if asked; :meth:`edge_items` of ``edge_stride`` and ``edge_rest``) then
        ``count`` random items, by role, clipped to nothing: the generators stay inside each
        field's range."""
        rng = np.random.default_rng([self.seed, salt])
        parts = []
        if edges:
            parts.append(self.edge_items(edge_stride, edge_rest))
        if count:
            parts.append(self.spec.random_inputs(rng, count, self.pm, self.k))
        out = {r: np.concatenate([p[r] for p in parts]).astype(np.int64) for r in self.spec.inputs}
        for role, name in self.bind_in.items():
            f = self.pm.i.fields[name]
            bad = (out[role] < f.lo) | (out[role] > f.hi)
            if bad.any():
                raise ValueError(f"stimulus for {role} outside field {name} range: {out[role][bad][:4]}")
        return out

    def expected(self, inputs, check_scalar: int = 256) -> dict[str, np.ndarray]:
        """Vector model over all items; the scalar model (the spec) on the first ``check_scalar``
        items and a random sample of as many more; any disagreement is a model error (raises)."""
        exp = {r: np.asarray(v, dtype=np.int64) for r, v in self.spec.model_vec(inputs, self.pm, self.k).items()}
        n = len(next(iter(inputs.values())))
        idx = list(range(min(n, check_scalar)))
        if n > check_scalar:
            idx += sorted(np.random.default_rng(self.seed).choice(np.arange(check_scalar, n),
                                                                  min(check_scalar, n - check_scalar), replace=False))
        for i in idx:
            want = self.spec.model_scalar({r: int(v[i]) for r, v in inputs.items()}, self.pm, self.k)
            got = {r: int(exp[r][i]) for r in want}
            if got != want:
                raise AssertionError(f"vector model != scalar model at {i}: inputs "
                                     f"{ {r: int(v[i]) for r, v in inputs.items()} } scalar {want} vector {got}")
        return exp


class Results:
    """Accumulates compared items, mismatches and timing; written to the job's result JSON."""

    def __init__(self, job: Job):
        self.job = job
        self.compared = 0
        self.mismatches = 0
        self.first_mismatch = None
        self.field_mismatches = {}      # output field -> items where it differs from the model
        self.tag_errors = 0
        self.stale_outputs = 0
        self.hold_violations = 0
        self.err_max = 0.0
        self.err_sq = 0.0
        self.err_n = 0
        self.sections = {}

    def mismatch(self, kind, inputs, expected, got, index=None):
        self.mismatches += 1
        if self.first_mismatch is None:
            self.first_mismatch = {"kind": kind, "index": index, "inputs": inputs, "expected": expected, "got": got}

    def count_fields(self, name: str, count: int) -> None:
        self.field_mismatches[name] = self.field_mismatches.get(name, 0) + int(count)

    def errors(self, inputs, got):
        err = np.asarray(self.job.spec.float_error(inputs, got, self.job.pm, self.job.k), dtype=np.float64)
        if err.size:
            self.err_max = max(self.err_max, float(err.max()))
            self.err_sq += float(np.sum(err * err))
            self.err_n += int(err.size)

    def write(self, path, extra=None):
        doc = {"compared": self.compared, "mismatches": self.mismatches, "first_mismatch": self.first_mismatch,
               "field_mismatches": {name: self.field_mismatches.get(name, 0) for name in self.job.bind_out.values()},
               "tag_errors": self.tag_errors, "stale_outputs": self.stale_outputs,
               "hold_violations": self.hold_violations,
               "max_error_lsb": self.err_max if self.err_n else None,
               "rms_error_lsb": (self.err_sq / self.err_n) ** 0.5 if self.err_n else None,
               "error_items": self.err_n, **self.sections, **(extra or {})}
        Path(path).write_text(json.dumps(doc, indent=1, default=_jsonable))
        return doc


def _jsonable(v):
    if isinstance(v, (np.integer,)):
        return int(v)
    if isinstance(v, (np.floating,)):
        return float(v)
    if isinstance(v, np.ndarray):
        return v.tolist()
    raise TypeError(type(v))
