"""Where a run of ``ik5r synth`` is: the phase of nextpnr read from the tail of its log, as one
line for a terminal (a placement of the pipelined q32w core on the ECP5-85k takes hours, most of
them in two phases that print nothing else), and the terminal table of the results."""

from __future__ import annotations

import re
import time
from pathlib import Path

#: (pattern, phase) tried on the log's lines from the newest back: the first that matches says
#: where nextpnr is. ``phase`` formats the match.
_PHASES = (
    (re.compile(r"iter=(\d+) wires=\d+ overused=(\d+)"),
     lambda m: f"routing (router2): iteration {m[1]}, {int(m[2]):,} wires overused"),
    (re.compile(r"^Info:\s+(\d+) \|[^|]*\|[^|]*\|\s*(\d+)\|"),
     lambda m: f"routing (router1): {int(m[2]):,} arcs left after {int(m[1]):,} iterations"),
    (re.compile(r"Routing (\d+) arcs"), lambda m: f"routing {int(m[1]):,} arcs"),
    (re.compile(r"Routing globals"), lambda m: "routing"),
    (re.compile(r"at iteration #(\d+): temp = [\d.]+, timing cost = \d+, wirelen = (\d+)"),
     lambda m: f"placement refinement (SA): iteration {m[1]}, wirelength {int(m[2]):,}"),
    (re.compile(r"Running simulated annealing placer"), lambda m: "placement refinement (SA)"),
    (re.compile(r"at iteration #(\d+), type \w+: wirelen solved = \d+, spread = \d+, legal = (\d+)"),
     lambda m: f"analytic placement (HeAP): iteration {m[1]}, wirelength {int(m[2]):,}"),
    (re.compile(r"initial (?:analytic placement|placer iter)"), lambda m: "analytic placement (HeAP): start"),
    (re.compile(r"Packing"), lambda m: "packing"),
)


def nextpnr_phase(log_path: Path, tail_bytes: int = 16384) -> str | None:
    """The phase the nextpnr run writing ``log_path`` is in (None: no log, or nothing known yet)."""
    try:
        with open(log_path, "rb") as log:
            log.seek(0, 2)
            log.seek(max(0, log.tell() - tail_bytes))
            lines = log.read().decode(errors="replace").splitlines()
    except OSError:
        return None
    for line in reversed(lines):
        for pattern, phase in _PHASES:
            match = pattern.search(line)
            if match:
                return phase(match)
    return None


class StatusLine:
    """One line of status on a terminal, rewritten in place with the time since its first
    :meth:`show`; :meth:`clear` it (or show None) before printing anything else."""

    def __init__(self, stream):
        self.stream, self.start, self.shown = stream, None, False

    def show(self, text: str | None) -> None:
        if text is None:
            self.clear()
            return
        now = time.monotonic()
        self.start = now if self.start is None else self.start
        elapsed = int(now - self.start)
        self.stream.write(f"\r\033[K[{elapsed // 3600}:{elapsed // 60 % 60:02d}:{elapsed % 60:02d}] {text}")
        self.stream.flush()
        self.shown = True

    def clear(self) -> None:
        if self.shown:
            self.stream.write("\r\033[K")
            self.stream.flush()
            self.shown = False


def summary_row(r: dict) -> list:
    """One row of the terminal / HTML table."""
    return [r["module"], r["config"], r["luts"], r["ffs"], r["carry"], r["dsps"], r["brams"],
            {True: "yes", False: "NO", None: "?"}[r.get("fits_device")],
            None if r["fmax_mhz"] is None else round(r["fmax_mhz"], 1), r["latency_cycles"],
            r["cycles_per_result"],
            None if r["results_per_second"] is None else r["results_per_second"] / 1e6]


SUMMARY_HEADER = ["module", "config", "LUTs", "FFs", "carry", "DSP", "BRAM", "fits", "Fmax MHz",
                  "latency", "cycles/result", "Mresults/s"]


def format_table(results: list[dict]) -> str:
    rows = [[("–" if v is None else (f"{v:.3g}" if isinstance(v, float) and i == len(SUMMARY_HEADER) - 1 else str(v)))
             for i, v in enumerate(summary_row(r))] for r in results]
    widths = [max(len(h), *(len(row[i]) for row in rows)) for i, h in enumerate(SUMMARY_HEADER)]
    line = lambda cells: "  ".join(c.rjust(w) if i else c.ljust(w) for i, (c, w) in enumerate(zip(cells, widths)))  # noqa: E731
    return "\n".join([line(SUMMARY_HEADER)] + [line(row) for row in rows])


def critical_path_line(r: dict) -> str | None:
    """The critical path of a result in one line (what to fix next): its total, logic and
    routing, its two ends and its longest route."""
    path = r.get("critical_path")
    if not path:
        return None
    routes = [step for step in path["steps"] if step["type"] == "routing"]
    longest = max(routes, key=lambda step: step["ns"], default=None)
    other = path["total_ns"] - path["logic_ns"] - path["routing_ns"]     # clock to out, setup
    return (f"critical path of {r['module']} {r['config']}: {path['total_ns']:.2f} ns = {path['logic_ns']:.2f} "
            f"logic + {path['routing_ns']:.2f} routing + {other:.2f} clock-to-out and setup, "
            f"{path['from_cell']} -> {path['to_cell']}"
            + (f"; longest route {longest['ns']:.2f} ns ({longest['name']})" if longest else ""))
