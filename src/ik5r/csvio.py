"""CSV files of the ``ik5r`` verbs: a header line of column names, then one record per line.

Reading is strict: a missing column, a field that is not a number or a record with the wrong
number of fields raises :class:`ik5r.errors.InputError` naming ``FILE:LINE`` (and the field).
Numbers are Python floats, so ``nan``, ``inf`` and ``-inf`` are read (and left for the caller to
flag per row). Columns may come in any order; extra columns are ignored. Blank lines are skipped.
Writing uses ``repr`` of floats (the shortest text that reads back to the same float64).
"""

from __future__ import annotations

import csv
import io
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .errors import InputError

#: Joint columns (radians), as ``ik5r fk`` reads them and ``ik5r solve`` writes them.
JOINT_COLUMNS = ("q1", "q2", "q3", "q4", "q5")
#: Pose columns, as ``ik5r fk`` writes them: tool point (cm), n, o, a.
POSE_COLUMNS = ("px", "py", "pz", "nx", "ny", "nz", "ox", "oy", "oz", "ax", "ay", "az")
POSITION_COLUMNS = ("px", "py", "pz")
APPROACH_COLUMNS = ("ax", "ay", "az")
ROLL_COLUMNS = ("nx", "ny", "nz", "ox", "oy", "oz")


class Table:
    """Numeric columns read from a CSV file: ``table[name]`` is a float64 (N,) array."""

    def __init__(self, path: str, header: list[str], columns: dict[str, np.ndarray], lines: np.ndarray):
        self.path, self.header, self.columns, self.lines = path, header, columns, lines

    def __len__(self) -> int:
        return len(self.lines)

    def __contains__(self, name: str) -> bool:
        return name in self.columns

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    def matrix(self, names: Sequence[str]) -> np.ndarray:
        """(N, len(names)) float64 array of the named columns."""
        return np.stack([self.columns[name] for name in names], axis=1) if len(self) else np.zeros((0, len(names)))


def _open_text(path) -> tuple[str, str]:
    if str(path) == "-":
        return "<stdin>", sys.stdin.read()
    try:
        return str(path), Path(path).read_text()
    except UnicodeDecodeError as exc:
        raise InputError(path, f"not a text file: {exc}") from exc
    except OSError as exc:
        raise InputError(path, exc.strerror or str(exc)) from exc


def read_table(path, required: Sequence[str], groups: Sequence[Sequence[str]] = ()) -> Table:
    """Read a CSV with at least the ``required`` columns; each of ``groups`` must be all present
    or all absent. ``path`` ``-`` reads standard input."""
    name, text = _open_text(path)
    reader = csv.reader(io.StringIO(text, newline=""))
    header = None
    for fields in reader:
        if fields and any(f.strip() for f in fields):
            header = [f.strip() for f in fields]
            break
    if header is None:
        raise InputError(name, "empty file: expected a header line with the column names", line=1)
    header_line = reader.line_num
    seen = set()
    for field in header:
        if not field:
            raise InputError(name, "empty column name in the header", line=header_line)
        if field in seen:
            raise InputError(name, "duplicate column in the header", line=header_line, field=field)
        seen.add(field)
    for column in required:
        if column not in seen:
            raise InputError(name, f"missing column (header has {', '.join(header)})",
                             line=header_line, field=column)
    wanted = list(required)
    for group in groups:
        present = [c for c in group if c in seen]
        if present and len(present) != len(group):
            missing = [c for c in group if c not in seen]
            raise InputError(name, f"columns {', '.join(group)} go together: {', '.join(missing)} missing",
                             line=header_line, field=missing[0])
        wanted += present
    index = [header.index(c) for c in wanted]
    width = len(header)
    rows: list[list[float]] = []
    lines: list[int] = []
    for fields in reader:
        if not fields or not any(f.strip() for f in fields):
            continue
        line = reader.line_num
        if len(fields) != width:
            raise InputError(name, f"expected {width} fields, got {len(fields)}", line=line)
        values = []
        for i in index:
            text_value = fields[i]
            try:
                values.append(float(text_value))
            except ValueError:
                raise InputError(name, f"not a number: {text_value.strip()!r}", line=line,
                                 field=header[i]) from None
        rows.append(values)
        lines.append(line)
    data = np.array(rows, dtype=np.float64).reshape(len(rows), len(wanted))
    columns = {c: data[:, j].copy() for j, c in enumerate(wanted)}
    return Table(name, header, columns, np.array(lines, dtype=np.int64))


def _format(column) -> list[str]:
    array = np.asarray(column)
    if array.dtype.kind == "f":
        return [repr(v) for v in array.tolist()]
    if array.dtype.kind in "iub":
        return [str(int(v)) for v in array.tolist()]
    return [str(v) for v in array.tolist()]


def write_table(path, names: Sequence[str], columns: Sequence) -> None:
    """Write columns (equal-length arrays or lists) under ``names``; ``path`` None or ``-``:
    standard output. Floats as ``repr`` (round-trip exact), integers as integers."""
    if len(names) != len(columns):
        raise ValueError("one column per name")
    formatted = [_format(c) for c in columns]
    lengths = {len(c) for c in formatted}
    if len(lengths) > 1:
        raise ValueError("columns differ in length")
    out = [",".join(names)]
    out.extend(",".join(fields) for fields in zip(*formatted))
    text = "\n".join(out) + "\n"
    if path is None or str(path) == "-":
        sys.stdout.write(text)
        sys.stdout.flush()
    else:
        try:
            Path(path).write_text(text)
        except OSError as exc:
            raise InputError(path, exc.strerror or str(exc)) from exc
