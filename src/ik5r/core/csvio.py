"""CSV files of the ``ik5r`` verbs: a header line of column names, then one record per line.

Reading is strict and streams: :class:`Reader` yields the records in chunks of ``chunk_rows``
(memory bounded whatever the file's length). A missing column, a field that is not a number or a
record with the wrong number of fields names ``FILE:LINE`` (and the field): with
``on_error="fail"`` (the default) it raises :class:`ik5r.core.errors.InputError`; with ``"skip"`` the
record is reported on ``stderr`` as ``FILE:LINE: message``, counted in ``Reader.skipped`` and left
out. A file that is not UTF-8 text, a header line that is missing (the first line holds numbers) or
wrong is always fatal. A UTF-8 byte-order mark is accepted. Numbers are Python floats, so ``nan``,
``inf`` and ``-inf`` are read (and left for the caller to flag per row); Python's digit separator
(``1_0``) is not a CSV number and is rejected. Columns may come in any order; extra columns are
ignored. Blank lines are skipped.

Writing (:class:`Writer`) goes to a temporary file beside the output, renamed over it only when
the verb succeeds; after a failure neither a partial nor an older output file is left. Floats are
written as ``repr`` (the shortest text that reads back to the same float64).
"""

from __future__ import annotations

import csv
import io
import os
import sys
import tempfile
from collections.abc import Iterator, Sequence
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
#: Records per chunk of :class:`Reader` (the verbs' memory does not grow with the file).
CHUNK_ROWS = 65536
ON_ERROR = ("fail", "skip")


class Table:
    """Numeric columns of a chunk of records: ``table[name]`` is a float64 (N,) array;
    ``lines`` the records' line numbers, ``records`` their 0-based index among the file's records
    (skipped ones included)."""

    def __init__(self, path: str, header: list[str], columns: dict[str, np.ndarray], lines: np.ndarray,
                 records: np.ndarray | None = None):
        self.path, self.header, self.columns, self.lines = path, header, columns, lines
        self.records = np.arange(len(lines)) if records is None else records

    def __len__(self) -> int:
        return len(self.lines)

    def __contains__(self, name: str) -> bool:
        return name in self.columns

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    def matrix(self, names: Sequence[str]) -> np.ndarray:
        """(N, len(names)) float64 array of the named columns."""
        return np.stack([self.columns[name] for name in names], axis=1) if len(self) else np.zeros((0, len(names)))


def parse_number(text: str) -> float:
    """A CSV number: what ``float`` reads, except Python's ``_`` digit separator (ValueError)."""
    if "_" in text:
        raise ValueError(text)
    return float(text)


def _is_number(text: str) -> bool:
    try:
        parse_number(text)
    except ValueError:
        return False
    return True


class Reader:
    """Stream a CSV with at least the ``required`` columns; each of ``groups`` must be all present
    or all absent. ``path`` ``-`` reads standard input. Use as a context manager; the header is
    read on entry (``header``, ``wanted``), :meth:`chunks` yields :class:`Table` chunks."""

    def __init__(self, path, required: Sequence[str], groups: Sequence[Sequence[str]] = (), *,
                 on_error: str = "fail", chunk_rows: int | None = None, stderr=None):
        if on_error not in ON_ERROR:
            raise ValueError(f"on_error must be one of {ON_ERROR}")
        self.path, self.required, self.groups = path, list(required), [list(g) for g in groups]
        self.on_error, self.stderr = on_error, stderr
        self.chunk_rows = CHUNK_ROWS if chunk_rows is None else chunk_rows
        self.name = "<stdin>" if str(path) == "-" else str(path)
        self.skipped = 0
        self._handle = None

    def __enter__(self) -> Reader:
        if str(self.path) == "-":
            buffer = getattr(sys.stdin, "buffer", None)
            self._handle = (io.TextIOWrapper(buffer, encoding="utf-8-sig", newline="")
                            if buffer is not None else sys.stdin)
        else:
            try:
                self._handle = open(self.path, encoding="utf-8-sig", newline="")
            except OSError as exc:
                raise InputError(self.path, exc.strerror or str(exc)) from None
        self._reader = csv.reader(self._handle)
        try:
            self._read_header()
        except BaseException:
            self.close()
            raise
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        if self._handle is not None and self._handle is not sys.stdin:
            if str(self.path) == "-":
                self._handle.detach()
            else:
                self._handle.close()
        self._handle = None

    def _next(self):
        """The next record's fields (None at the end); undecodable text or a CSV syntax error
        is fatal (the reader cannot find the next record)."""
        try:
            return next(self._reader)
        except StopIteration:
            return None
        except UnicodeDecodeError as exc:
            raise InputError(self.name, f"not UTF-8 text: {exc.reason}", line=self._reader.line_num + 1) from None
        except csv.Error as exc:
            raise InputError(self.name, f"not CSV: {exc}", line=self._reader.line_num) from None

    def _read_header(self) -> None:
        name = self.name
        while (fields := self._next()) is not None:
            if any(f.strip() for f in fields):
                break
        if fields is None:
            raise InputError(name, "empty file: expected a header line with the column names", line=1)
        header = [f.strip() for f in fields]
        line = self._reader.line_num
        if all(_is_number(f) for f in header):
            raise InputError(name, "header missing: the first line holds numbers; expected the column "
                             f"names ({','.join(self.required)}, ...)", line=line)
        seen = set()
        for field in header:
            if not field:
                raise InputError(name, "empty column name in the header", line=line)
            if field in seen:
                raise InputError(name, "duplicate column in the header", line=line, field=field)
            seen.add(field)
        for column in self.required:
            if column not in seen:
                raise InputError(name, f"missing column (header has {', '.join(header)})", line=line,
                                 field=column)
        wanted = list(self.required)
        for group in self.groups:
            present = [c for c in group if c in seen]
            if present and len(present) != len(group):
                missing = [c for c in group if c not in seen]
                raise InputError(name, f"columns {', '.join(group)} go together: {', '.join(missing)} missing",
                                 line=line, field=missing[0])
            wanted += present
        self.header, self.wanted = header, wanted
        self._index = [header.index(c) for c in wanted]

    def _parse(self, fields: list[str], line: int) -> list[float]:
        if len(fields) != len(self.header):
            raise InputError(self.name, f"expected {len(self.header)} fields, got {len(fields)}", line=line)
        try:
            # The common case in one comprehension (the reader's hot loop); '_' anywhere sends
            # the record through the field-by-field check.
            if "_" not in "".join(fields):
                return [float(fields[i]) for i in self._index]
        except ValueError:
            pass
        values = []
        for i in self._index:
            try:
                values.append(parse_number(fields[i]))
            except ValueError:
                raise InputError(self.name, f"not a number: {fields[i].strip()!r}", line=line,
                                 field=self.header[i]) from None
        return values

    def chunks(self) -> Iterator[Table]:
        """Tables of up to ``chunk_rows`` good records each (at least one table, maybe empty)."""
        rows, lines, records, record, yielded = [], [], [], 0, False
        while (fields := self._next()) is not None:
            if not fields or (not fields[0].strip() and not any(f.strip() for f in fields)):
                continue            # a blank record
            line = self._reader.line_num
            try:
                rows.append(self._parse(fields, line))
            except InputError as exc:
                if self.on_error == "fail":
                    raise
                self.skipped += 1
                print(exc, file=self.stderr or sys.stderr)
            else:
                lines.append(line)
                records.append(record)
            record += 1
            if len(rows) >= self.chunk_rows:
                yield self._table(rows, lines, records)
                rows, lines, records, yielded = [], [], [], True
        if rows or not yielded:
            yield self._table(rows, lines, records)

    def _table(self, rows, lines, records) -> Table:
        data = np.array(rows, dtype=np.float64).reshape(len(rows), len(self.wanted))
        columns = {c: data[:, j].copy() for j, c in enumerate(self.wanted)}
        return Table(self.name, self.header, columns, np.array(lines, dtype=np.int64),
                     np.array(records, dtype=np.int64))


def read_table(path, required: Sequence[str], groups: Sequence[Sequence[str]] = ()) -> Table:
    """The whole file as one :class:`Table` (fail-fast); for small files and tests."""
    with Reader(path, required, groups, chunk_rows=1 << 62) as reader:
        return next(iter(reader.chunks()))


def _format(column) -> list[str]:
    array = np.asarray(column)
    if array.dtype.kind == "f":
        return [repr(v) for v in array.tolist()]
    if array.dtype.kind in "iub":
        return [str(int(v)) for v in array.tolist()]
    return [str(v) for v in array.tolist()]


def check_writable(path) -> None:
    """InputError unless a file could be created at ``path`` (its folder exists and is writable,
    and ``path`` is not a folder)."""
    target = Path(path)
    parent = target.parent
    if target.is_dir():
        raise InputError(path, "is a directory, expected a file name")
    if not parent.is_dir():
        raise InputError(path, f"folder {str(parent)!r} does not exist" if not parent.exists()
                         else f"{str(parent)!r} is not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(path, f"folder {str(parent)!r} is not writable")


class Writer:
    """A CSV output written in chunks: standard output (``path`` None or ``-``), or a temporary
    file beside ``path`` renamed over it when the ``with`` block ends without an exception. After
    an exception the temporary file and any older file at ``path`` are removed (no stale or
    partial output)."""

    def __init__(self, path, names: Sequence[str]):
        self.path = None if path is None or str(path) == "-" else Path(path)
        self.names = list(names)
        self._temp = None
        if self.path is not None:
            check_writable(self.path)

    def __enter__(self) -> Writer:
        if self.path is None:
            self._out = sys.stdout
        else:
            try:
                fd, temp = tempfile.mkstemp(dir=self.path.parent, prefix=f".{self.path.name}.", suffix=".tmp")
            except OSError as exc:
                raise InputError(self.path, exc.strerror or str(exc)) from None
            self._temp = Path(temp)
            self._out = os.fdopen(fd, "w", newline="")
        self._header_done = False
        return self

    def _header(self) -> None:
        if not self._header_done:
            self._header_done = True
            self._emit(",".join(self.names) + "\n")

    def _emit(self, text: str) -> None:
        try:
            self._out.write(text)
        except OSError as exc:
            raise InputError(self.path or "<stdout>", exc.strerror or str(exc)) from None

    def write(self, columns: Sequence) -> None:
        """Append records: one equal-length array or list per name."""
        if len(columns) != len(self.names):
            raise ValueError("one column per name")
        formatted = [_format(c) for c in columns]
        if len({len(c) for c in formatted}) > 1:
            raise ValueError("columns differ in length")
        self._header()
        if formatted and formatted[0]:
            self._emit("".join(",".join(fields) + "\n" for fields in zip(*formatted)))

    def __exit__(self, kind, exc, tb) -> None:
        if kind is None:
            self._header()
        if self.path is None:
            if kind is None:
                self._out.flush()
            return
        failed = kind is not None
        try:
            self._out.close()
            if not failed:
                os.replace(self._temp, self.path)
                self._temp = None
        except OSError as err:
            failed = True
            if exc is None:
                raise InputError(self.path, err.strerror or str(err)) from None
        finally:
            if self._temp is not None:
                self._temp.unlink(missing_ok=True)
            if failed:
                self.path.unlink(missing_ok=True)


def write_table(path, names: Sequence[str], columns: Sequence) -> None:
    """Write columns (equal-length arrays or lists) under ``names`` in one go; ``path`` None or
    ``-``: standard output. Floats as ``repr`` (round-trip exact), integers as integers."""
    with Writer(path, names) as writer:
        writer.write(columns)
