"""Strict, kind inputs and big files: malformed CSV and TOML classes (exit 2, FILE:LINE or FILE and
field, no traceback, no stale output), bad paths for every verb, ``--on-error skip`` (exit 3,
every good row written) and chunked streaming (the same output whatever the chunk size)."""

from __future__ import annotations

import argparse
import csv
import io
import math
import sys

import numpy as np
import pytest

from ik5r.core import csvio
from ik5r.core import reference as ref
from ik5r.core.arm import load_arm
from ik5r.core.errors import InputError
from ik5r.core.fxconfig import config_dir, load_config
from ik5r.tools.cli import VERBS, build_parser, main

ARM = load_arm()
POSE_HEADER = ",".join(csvio.POSE_COLUMNS)


def _poses(tmp_path, count=50, seed=3):
    q = ref.random_joints(ARM, count, np.random.default_rng(seed))
    pose = ref.fk_pose(ARM, q)
    path = tmp_path / "poses.csv"
    path.write_text(POSE_HEADER + "\n" + "".join(",".join(repr(v) for v in row) + "\n" for row in pose.tolist()))
    return path


def _one_line_error(capsys, code, got, needle):
    captured = capsys.readouterr()
    assert got == code, captured.err
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in captured.err, captured.err
    assert needle in lines[0], lines[0]
    return lines[0]


# ---- config TOML -------------------------------------------------------------------------------

@pytest.mark.parametrize("edit, field", [
    (lambda t: t.replace("internal_guard_bits =", "internal_guard_bit ="), "ik.internal_guard_bit"),
    (lambda t: t.replace('rounding = "nearest"', 'roundng = "nearest"'), "ik.roundng"),
    (lambda t: "colour = 3\n" + t, "colour"),
    (lambda t: t + "\n[extra]\nx = 1\n", "extra"),
    (lambda t: t.replace("[frac]", "frac = 3\n[fracs]"), "frac"),
])
def test_config_unknown_key_rejected(tmp_path, capsys, edit, field):
    path = tmp_path / "bad.toml"
    path.write_text(edit((config_dir() / "q18.toml").read_text()))
    with pytest.raises(InputError) as info:
        load_config(path)
    assert str(info.value).startswith(f"{path}: field '{field}'")
    got = main(["verilog", "--block", "sqrt", "--config", str(path), "-o", str(tmp_path / "v")])
    _one_line_error(capsys, 2, got, f"field '{field}'")


def test_config_with_bom_reads_as_without(tmp_path):
    text = (config_dir() / "q18.toml").read_text()
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf" + text.encode())
    assert load_config(path).width == load_config("q18").width


# ---- CSV ---------------------------------------------------------------------------------------

def test_bom_accepted_and_same_output(tmp_path):
    path = _poses(tmp_path)
    bom = tmp_path / "bom.csv"
    bom.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    outs = []
    for src in (path, bom):
        out = tmp_path / f"{src.stem}.out.csv"
        assert main(["solve", str(src), "-o", str(out)]) == 0
        outs.append(out.read_text())
    assert outs[0] == outs[1]


@pytest.mark.parametrize("text, line, needle", [
    ("q1,q2,q3,q4,q5\n0,0,1_0,0,0\n", 2, "field 'q3': not a number: '1_0'"),
    ("0,0,0,0,0\n1,2,3,4,5\n", 1, "header missing"),
    ("q1,q2,q3,q4,q5\n0,0,\xff,0,0\n", None, "not a number"),
    ("q1,q2,q3,q4,q5\n0,0,0,0\n", 2, "expected 5 fields, got 4"),
    ("q1,q2,q3,q4,q5\n0,0,\"1,0,0\n", 2, "expected 5 fields"),
    ("q1,q1,q3,q4,q5\n", 1, "field 'q1': duplicate column"),
])
def test_malformed_joints_classes(tmp_path, capsys, text, line, needle):
    path = tmp_path / "j.csv"
    path.write_text(text)
    first = _one_line_error(capsys, 2, main(["fk", str(path)]), needle)
    assert first.startswith(f"{path}:{line}: " if line else f"{path}:")


def test_not_utf8_is_one_line(tmp_path, capsys):
    path = tmp_path / "j.csv"
    path.write_bytes(b"q1,q2,q3,q4,q5\n0,0,0,0,0\n0,\xff\xfe,0,0,0\n")
    first = _one_line_error(capsys, 2, main(["fk", str(path)]), "not UTF-8 text")
    assert first.startswith(f"{path}:")


def test_failure_leaves_no_stale_or_partial_output(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(csvio, "CHUNK_ROWS", 7)        # a good chunk is written before the bad row
    path = _poses(tmp_path, 30)
    lines = path.read_text().splitlines()
    lines[25] = lines[25].replace(",", ";", 1)
    path.write_text("\n".join(lines) + "\n")
    out = tmp_path / "out.csv"
    out.write_text("an older result\n")
    assert main(["solve", str(path), "-o", str(out)]) == 2
    assert f"{path}:26: expected 12 fields, got 11" in capsys.readouterr().err
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["poses.csv"]      # no temporary file


def test_on_error_skip_writes_every_good_row(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(csvio, "CHUNK_ROWS", 8)
    path = _poses(tmp_path, 40)
    good_text = path.read_text()
    lines = good_text.splitlines()
    bad_lines = {3: "1,2,3", 11: lines[11].replace(lines[11].split(",")[0], "x1", 1), 40: "1_0," + lines[40]}
    for line_no, text in bad_lines.items():
        lines[line_no - 1] = text
    path.write_text("\n".join(lines) + "\n")
    for solver in ("float", "fixed", "c"):
        out = tmp_path / f"{solver}.csv"
        assert main(["solve", str(path), "-o", str(out), "--solver", solver, "--on-error", "skip"]) == 3
        err = capsys.readouterr().err.strip().splitlines()
        assert [e.split(": ")[0] for e in err] == [f"{path}:{n}" for n in sorted(bad_lines)]
        with open(out, newline="") as handle:
            rows = list(csv.DictReader(handle))
        good_records = [i for i in range(40) if i + 2 not in bad_lines]
        assert [int(r["row"]) for r in rows] == good_records
        # the good rows' answers are those of a run on the good rows alone
        clean = tmp_path / "clean.csv"
        clean.write_text("\n".join([lines[0]] + [lines[i + 1] for i in good_records]) + "\n")
        ref_out = tmp_path / "ref.csv"
        assert main(["solve", str(clean), "-o", str(ref_out), "--solver", solver]) == 0
        with open(ref_out, newline="") as handle:
            expected = list(csv.DictReader(handle))
        assert [{**r, "row": ""} for r in rows] == [{**r, "row": ""} for r in expected]
    assert main(["solve", str(path), "-o", str(tmp_path / "f.csv")]) == 2     # default: fail fast


def test_fk_on_error_skip(tmp_path, capsys):
    path = tmp_path / "j.csv"
    path.write_text("q1,q2,q3,q4,q5\n0,0,0,0,0\nnope\n0.1,0,0,0,0\n")
    out = tmp_path / "p.csv"
    assert main(["fk", str(path), "-o", str(out), "--on-error", "skip"]) == 3
    assert capsys.readouterr().err.startswith(f"{path}:3: expected 5 fields, got 1")
    assert len(out.read_text().splitlines()) == 3


@pytest.mark.parametrize("solver", ["float", "fixed"])
def test_chunked_output_equals_one_chunk(tmp_path, monkeypatch, solver):
    path = _poses(tmp_path, 45)
    outs = []
    for chunk in (10**9, 4):
        monkeypatch.setattr(csvio, "CHUNK_ROWS", chunk)
        out = tmp_path / f"o{chunk}.csv"
        assert main(["solve", str(path), "-o", str(out), "--all", "--solver", solver]) == 0
        outs.append(out.read_text())
    assert outs[0] == outs[1] and len(outs[0].splitlines()) > 45


def test_stdin_with_bom(monkeypatch, capsys, tmp_path):
    data = b"\xef\xbb\xbfq1,q2,q3,q4,q5\n0,-1.5707963267948966,0,-1.5707963267948966,0\n"
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(data)))
    assert main(["fk", "-"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == POSE_HEADER and len(lines) == 2
    assert math.isclose(float(lines[1].split(",")[2]), 34.0)


# ---- every verb: bad input and bad output paths ----------------------------------------------------

def _subparser(verb) -> argparse.ArgumentParser:
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices[verb]


def _base_args(verb, bad_input):
    """Required arguments of a verb: positionals get ``bad_input``, required choices their first."""
    args = [verb]
    for action in _subparser(verb)._actions:
        if not action.option_strings and action.dest != "help":
            args.append(bad_input)
        elif action.required and action.option_strings:
            value = str(action.choices[0]) if action.choices else "32" if action.type is int else bad_input
            args += [action.option_strings[-1], value]
    return args


def _options(verb):
    return {a.dest: a.option_strings[-1] for a in _subparser(verb)._actions if a.option_strings}


#: Verbs that read and write no file (``ik5r arms`` lists the shipped arms).
PATHLESS_VERBS = ("arms",)


def test_only_the_listing_verbs_take_no_path():
    takes_path = {v for v in VERBS if any(not a.option_strings and a.dest != "help" for a in _subparser(v)._actions)
                  or set(_options(v)) & {"config", "arm", "output", "json", "cache", "synth_cache"}}
    assert set(VERBS) - takes_path == set(PATHLESS_VERBS)


@pytest.mark.parametrize("verb", [v for v in VERBS if v not in PATHLESS_VERBS])
def test_every_verb_bad_paths_exit_2(tmp_path, capsys, verb):
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    missing = str(tmp_path / "missing" / "in.csv")
    options = _options(verb)
    cases = []
    inputs = [d for d in ("config", "arm") if d in options]
    positional = any(not a.option_strings and a.dest != "help" for a in _subparser(verb)._actions)
    good_input = str(_poses(tmp_path, 3)) if positional else missing
    if positional:
        cases.append((_base_args(verb, missing), missing))
    for dest in inputs:
        cases.append((_base_args(verb, good_input) + [options[dest], missing], missing))
    for dest in ("output", "json", "cache", "synth_cache"):
        if dest in options:
            bad_out = str(blocker / "sub" / "out")
            cases.append((_base_args(verb, good_input) + [options[dest], bad_out], bad_out))
    assert cases, f"{verb}: no path argument found"
    for argv, needle in cases:
        got = main(argv)
        _one_line_error(capsys, 2, got, needle)
