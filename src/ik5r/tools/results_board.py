"""The README's board table (issue 28): ``ik5r board`` records, kept only when their bitstream was
built from the RTLIL this checkout generates, and the simulated link's record."""

from __future__ import annotations

import json
from pathlib import Path

from .results_arms import _num     # the same number format as the other tables


#: Per family: (logic cells, block RAMs, DSPs) in a board record's nextpnr utilisation.
_BOARD_CELLS = {"ice40": ("ICESTORM_LC", "ICESTORM_RAM", "ICESTORM_DSP"),
                "ecp5": ("TRELLIS_COMB", "DP16KD", "MULT18X18D")}


class BoardOfCheckout:
    """The SHA-256 of the RTLIL this checkout gives Yosys for a board record's build (memoised)."""

    def __init__(self):
        self._shas = {}

    def sha256(self, r: dict) -> str | None:
        """None: the record's arm or config is not one this checkout can build again."""
        from ik5r.core.arm import load_arm
        from ik5r.core.errors import InputError
        from ik5r.core.fxconfig import constants, load_config

        from .board import plan, rtlil_sha256

        key = (r["board"], r["config"], r.get("arm"), r["baud"], r["core"])
        if key not in self._shas:
            try:
                k = constants(load_config(r["config"]), load_arm(r.get("arm")))
                self._shas[key] = rtlil_sha256(plan(r["board"], k, baud=r["baud"], core=r["core"])[0])
            except InputError:
                self._shas[key] = None
        return self._shas[key]

    def current(self, r: dict) -> bool:
        """Whether the record's bitstream was built from what this checkout generates (records
        made before the hash was kept count as not current)."""
        return r.get("rtlil_sha256") is not None and r["rtlil_sha256"] == self.sha256(r)


def board_builds(records: Path, boards: BoardOfCheckout) -> tuple[list[dict], list[str]]:
    """The board records of this checkout's RTLIL, and the names of the others."""
    builds, stale = [], []
    for path in sorted((records / "board").glob("*.json")):
        if path.name.startswith("sim_link"):
            continue
        r = json.loads(path.read_text())
        if boards.current(r):
            builds.append(r)
        else:
            stale.append(f"board/{path.name}")
    return builds, stale


def board_part(records: Path, builds: list[dict]) -> list[str]:
    """On a real board (issue 28): the ``ik5r board`` records ``builds`` and the simulated link's record."""
    paths = sorted((records / "board").glob("*.json"))
    lines = ["| board | core | config | clock (MHz) | baud | Fmax (MHz) | timing | LUTs | BRAMs | DSPs | "
             "bitstream (bytes) | poses/s at line rate | core poses/s |",
             "| --- | --- | --- | ---: | ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in builds:
        family = "ice40" if "ICESTORM_LC" in r["resources"] else "ecp5"
        used = [r["resources"].get(cell, {}).get("used") for cell in _BOARD_CELLS[family]]
        lines.append(f"| {r['board']} | {r['core']} | {r['config']} | {r['clock_mhz']:g} | {r['baud']:,} | "
                     f"{_num(r.get('fmax_mhz'), '{:.1f}')} | {'met' if r['timing_met'] else 'not met'} | "
                     f"{_num(used[0])} | {_num(used[1])} | {_num(used[2])} | {_num(r['bitstream_bytes'])} | "
                     f"{_num(r['line_poses_per_s'])} | {_num(r.get('core_poses_per_s'))} |")
    if not builds:
        lines = ["No board build yet: run `ik5r board --board icebreaker --record`."]
    for p in paths:
        if p.name.startswith("sim_link"):
            r = json.loads(p.read_text())
            lines += ["", f"Simulated link (`python -m ik5r.tools.boardsim --record`: the iCEBreaker top level in "
                      f"Verilator, UART on a TCP socket, the host client): {r['poses']:,} {r['config']} poses, "
                      f"{r['differing_words']} differing words, {r['poses_per_s']:,.0f} poses/s in simulated time at "
                      f"{r['baud']:,} baud = {100 * r['poses_per_s'] / r['line_poses_per_s']:.1f}% of the line-rate "
                      f"bound ({r['line_poses_per_s']:,.0f})."]
    return lines
