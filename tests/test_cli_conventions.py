"""Command-line conventions: --version, python -m ik5r, -q/-v on every verb, plain help, progress
bars only on a terminal, NO_COLOR / TERM=dumb, --config NAME from any directory."""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys

import pytest

from ik5r import __version__
from ik5r.tools import cliopts
from ik5r.tools.cli import build_parser, main


def _verbs() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def test_version_and_python_dash_m(tmp_path):
    done = subprocess.run([sys.executable, "-m", "ik5r", "--version"], capture_output=True, text=True,
                          cwd=tmp_path)
    assert done.returncode == 0 and done.stdout.strip() == f"ik5r {__version__}"
    done = subprocess.run([sys.executable, "-m", "ik5r", "fk", "--help"], capture_output=True, text=True,
                          cwd=tmp_path)
    assert done.returncode == 0 and done.stdout.startswith("usage: ik5r fk")


def test_every_verb_takes_quiet_and_verbose():
    verbs = _verbs()
    assert {"fk", "solve", "report", "verilog", "sim", "synth", "sweep"} <= set(verbs)
    for name, parser in verbs.items():
        options = parser._option_string_actions
        for flag in ("-q", "--quiet", "-v", "--verbose"):
            assert flag in options, (name, flag)


def test_help_is_plain_text():
    for name, parser in _verbs().items():
        text = parser.format_help()
        assert "``" not in text and not re.search(r":(mod|func|class|meth):", text), name
    assert "``" not in build_parser().format_help()


def test_errors_name_no_internal_function(capsys):
    for argv in (["report", "--vectors", "many", "-o", "x"], ["report", "--vectors", "0", "-o", "x"],
                 ["sweep", "--widths", "a,b"]):
        with pytest.raises(SystemExit) as exc:
            main(argv)
        assert exc.value.code == 2
        err = capsys.readouterr().err
        assert "argument --" in err and not re.search(r"invalid _\w+ value", err), err


def test_progress_only_on_a_terminal(monkeypatch):
    class Stream:
        def __init__(self, tty):
            self.tty = tty

        def isatty(self):
            return self.tty

    args = argparse.Namespace(quiet=False, no_progress=False, verbose=0)
    assert cliopts.show_progress(args, Stream(True)) is True
    assert cliopts.show_progress(args, Stream(False)) is False
    assert cliopts.show_progress(argparse.Namespace(quiet=True), Stream(True)) is False
    assert cliopts.show_progress(argparse.Namespace(no_progress=True), Stream(True)) is False
    monkeypatch.delenv("NO_COLOR", raising=False)
    monkeypatch.setenv("TERM", "xterm")
    assert cliopts.colour("ok", True, Stream(True)) == "\033[32mok\033[0m"
    assert cliopts.colour("ok", True, Stream(False)) == "ok"
    monkeypatch.setenv("NO_COLOR", "1")
    assert cliopts.colour("ok", True, Stream(True)) == "ok"
    monkeypatch.delenv("NO_COLOR")
    monkeypatch.setenv("TERM", "dumb")
    assert cliopts.colour("bad", False, Stream(True)) == "bad"


def test_redirected_report_has_no_progress_bar(tmp_path, capsys):
    done = subprocess.run([sys.executable, "-m", "ik5r", "report", "--vectors", "500", "-o", str(tmp_path / "r")],
                          capture_output=True, text=True, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert "\r" not in done.stderr and "chunk/s" not in done.stderr
    assert "fixed beats float32" in done.stdout
    assert main(["report", "--vectors", "500", "-q", "-o", str(tmp_path / "q")]) == 0
    quiet = capsys.readouterr()
    assert quiet.err == "" and quiet.out.splitlines() == [f"report: {tmp_path / 'q'}/index.html"]


def test_config_names_resolve_from_any_directory(tmp_path, capsys, monkeypatch):
    from ik5r.core.fxconfig import config_dir, load_config

    monkeypatch.chdir(tmp_path)
    assert not (tmp_path / "configs").exists()
    for given in ("q18", "configs/q18.toml"):
        cfg = load_config(given)
        assert cfg.name == "q18" and os.path.samefile(cfg.source, config_dir() / "q18.toml")
    own = tmp_path / "mine.toml"
    own.write_text((config_dir() / "q24.toml").read_text().replace('name = "q24"', 'name = "mine"'))
    assert load_config(str(own)).name == "mine" and load_config("mine.toml").name == "mine"
    assert main(["report", "--config", "nonesuch", "--vectors", "10", "-o", "r"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("nonesuch: ") and "q32w" in err and len(err.splitlines()) == 1
