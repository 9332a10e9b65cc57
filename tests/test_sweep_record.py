"""The sweep's typed options and record (ik5r.tools.sweep_record): the one place sweep.json is
written and read, with the keys of the records already kept."""

from __future__ import annotations

from pathlib import Path

import pytest

from ik5r.tools.sweep_record import RECORD_FILE, SweepOptions, SweepRecord

RECORD = Path(__file__).resolve().parent.parent / "docs" / "results" / "records" / RECORD_FILE


def test_kept_record_reads_and_writes_back_byte_for_byte(tmp_path):
    """The record of docs/results read and written again is the same file: the JSON keys (and
    layout) are those the records were made with."""
    record = SweepRecord.read(RECORD)
    assert record.points and {"name", "block", "arch", "width", "position_err_max_cm"} <= set(record.points[0])
    assert record.meta["failures"] == record.failures
    path = record.write(tmp_path)
    assert path.read_text() == RECORD.read_text()
    assert SweepRecord.read(tmp_path) == record


def test_options_are_frozen_and_hashable():
    a = SweepOptions(widths=range(12, 15), guard_bits=[0, 6], synth=False)
    assert a.widths == (12, 13, 14) and a.guard_bits == (0, 6) and a == SweepOptions(widths=(12, 13, 14),
                                                                                      guard_bits=(0, 6), synth=False)
    hash(a)
    with pytest.raises(AttributeError):
        a.poses = 1
