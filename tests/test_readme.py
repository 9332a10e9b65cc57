"""The README's quick start, run as written: every ``ik5r`` line of its shell block, in a copy of
the checkout's ``examples/``, and the output the README shows compared with what the run prints."""

from __future__ import annotations

import re
import shlex
import shutil
from pathlib import Path

from ik5r.tools.cli import main

ROOT = Path(__file__).resolve().parents[1]


def _section(text: str, title: str) -> str:
    start = text.index(f"## {title}\n")
    end = text.index("\n## ", start + 1)
    return text[start:end]


def _blocks(section: str) -> list[tuple[str, str]]:
    """(language, body) of each fenced block of a README section."""
    return re.findall(r"```(\w*)\n(.*?)```", section, flags=re.S)


def _quick_start() -> tuple[list[list[str]], str, str]:
    section = _section((ROOT / "README.md").read_text(encoding="utf-8"), "Quick start")
    blocks = _blocks(section)
    commands = [shlex.split(line, comments=True) for line in blocks[0][1].splitlines()]
    commands = [c for c in commands if c and c[0] == "ik5r"]
    return commands, blocks[1][1], blocks[2][1]


def test_quick_start_runs_as_written(tmp_path, monkeypatch, capsys):
    commands, solve_shown, report_shown = _quick_start()
    assert [c[1] for c in commands] == ["--version", "fk", "solve", "report"]
    shutil.copytree(ROOT / "examples", tmp_path / "examples")
    monkeypatch.chdir(tmp_path)
    printed = {}
    for argv in commands[1:]:
        capsys.readouterr()
        assert main(argv[1:]) == 0, argv
        printed[argv[1]] = capsys.readouterr().out
    # fk: "(= examples/poses.csv)"
    assert (tmp_path / "my_poses.csv").read_bytes() == (tmp_path / "examples" / "poses.csv").read_bytes()
    # solve: each line shown is the start of the printed line (the README cuts them at "...")
    solve_lines = printed["solve"].splitlines()
    for shown, got in zip(solve_shown.splitlines(), solve_lines, strict=False):
        assert got.startswith(shown.removesuffix("...")), (shown, got)
    assert len(solve_shown.splitlines()) == len(solve_lines)
    # report: the terminal summary the README quotes, line for line (the path is the run's)
    for line in report_shown.splitlines():
        assert line in printed["report"], line
    assert (tmp_path / "build" / "quick" / "index.html").is_file()
