"""The placement of a program's blocks as a constraint problem, solved by CP-SAT (OR-Tools).

The list scheduler (:mod:`.schedule`) places blocks one at a time in an order, each at its first
free clock; a search over orders (:mod:`.search`) only reaches the placements some order gives.
Here every block's start is a variable of one model, with exactly the placer's rules:

- a block's claims (:class:`.schedule.Block`: instruction fields, B bus, memory ports, the
  accumulator, F flag and unit spans), each run of consecutive clocks an interval at a fixed
  offset from the block's start: per claim, no two intervals overlap;
- the conditions: an ALU operation and a CORDIC load in the same clock act under one condition
  (the engine has one), so per condition the ALU operations under it and the loads under any
  other do not overlap, nor the loads under it and the ALU operations under any other;
- a read READ_AHEAD + 1 clocks or more after its word's store, the blocks after the input block,
  the order constraints between the poses' word ports (``after``), the output block after every
  other block ends;
- the program's length, the output block's end, minimised.

With ``modulo``, the blocks are one pose's, placed as the template of a modulo schedule
(:mod:`.modulo`): a pose every ``period`` clocks, the claims taken modulo the period (each
interval also as its copies one and two periods earlier: a pose lies within two periods, the
span of the two-pose engine's two register sets, and an interval is shorter than a period);
the period minimised.

The solver returns the best placement found in its time and a proven lower bound on the length:
how far any placement of these blocks on these units can go. A placement is kept as the
starts of :func:`.schedule.placed` (each block no earlier than its start; a valid placement is
then reproduced exactly, whatever the order). OR-Tools is imported only here: the offline search
needs it, a compile of a kept placement does not.
"""

from __future__ import annotations

from dataclasses import dataclass

from .isa import READ_AHEAD
from .program import INPUT_GAP
from .schedule import LOADS, _dependencies

__all__ = ["Placement", "solve"]


@dataclass(frozen=True)
class Placement:
    """The solver's result: per block its start, the program's length (a modulo template's:
    its period), the proven lower bound on it, and whether the length is that bound (optimal)."""
    starts: list
    clocks: int
    bound: int
    optimal: bool


def _runs(offsets) -> list[tuple[int, int]]:
    """Consecutive offsets as (first, length) runs."""
    runs: list[list[int]] = []
    for t in sorted(set(offsets)):
        if runs and runs[-1][0] + runs[-1][1] == t:
            runs[-1][1] += 1
        else:
            runs.append([t, 1])
    return [(t, n) for t, n in runs]


class _Model:
    """The CP-SAT model of placing ``blocks`` in at most ``horizon`` clocks (``modulo``: as a
    modulo schedule's template, see the module docstring)."""

    def __init__(self, blocks, horizon: int, modulo: bool = False):
        try:
            from ortools.sat.python import cp_model
        except ImportError as e:
            raise ImportError("the constraint solver's search needs OR-Tools: pip install 'ik5r[search]'") from e
        self.cp, self.blocks = cp_model, blocks
        self.m = m = cp_model.CpModel()
        self.start = [m.new_int_var(0, horizon, f"s{i}") for i in range(len(blocks))]
        self.end = m.new_int_var(0, horizon, "end")
        self.period, self.early = None, [[] for _ in blocks]
        self._order()
        if modulo:
            self._modulo(horizon)
        self._claims()
        self._conditions()
        m.minimize(self.period if modulo else self.end)

    def _modulo(self, horizon: int):
        """The period, each block's starts one and two periods earlier, a pose within two
        periods, the next pose's inputs after this one's."""
        m, s, blocks = self.m, self.start, self.blocks
        self.period = period = m.new_int_var(1, horizon // 2, "period")
        for i, start in enumerate(s):
            for k in (1, 2):
                early = m.new_int_var(-horizon, horizon, f"e{i}_{k}")
                m.add(early == start - k * period)
                self.early[i].append(early)
        m.add(s[-1] + len(blocks[-1].code) <= s[0] + 2 * period)
        m.add(len(blocks[0].code) + INPUT_GAP <= period)
        m.add(len(blocks[-1].code) <= period)

    def _order(self):
        m, s, blocks = self.m, self.start, self.blocks
        producer, _, _ = _dependencies(blocks)
        last = len(blocks) - 1
        m.add(s[0] == 0)
        for j, b in enumerate(blocks):
            if j:
                m.add(s[j] >= len(blocks[0].code))
            for t_read, name in b.reads:
                i, t_write = producer[name]
                if i != j:
                    m.add(s[j] + t_read >= s[i] + t_write + READ_AHEAD + 1)
            for before, gap in getattr(blocks, "after", {}).get(j, ()):
                m.add(s[j] >= s[before] + len(blocks[before].code) + gap)
            if j != last:
                m.add(s[last] >= s[j] + len(b.code))
        m.add(self.end == s[last] + len(blocks[last].code))

    def _intervals(self, i: int, offsets) -> list:
        return [self.m.new_fixed_size_interval_var(start + t, n, f"b{i}@{t}")
                for start in (self.start[i], *self.early[i]) for t, n in _runs(offsets)]

    def _claims(self):
        per_claim: dict[int, list] = {}
        for i, b in enumerate(self.blocks):
            for bit, offsets in b.offsets.items():
                per_claim.setdefault(bit, []).extend(self._intervals(i, offsets))
        for intervals in per_claim.values():
            if len(intervals) > 1:
                self.m.add_no_overlap(intervals)

    def _conditions(self):
        alu, load = {}, {}          # (block, condition) -> offsets
        for i, b in enumerate(self.blocks):
            for t, cond in enumerate(b.conds[:len(b.code)]):
                if cond is not None and b.code[t].alu is not None:
                    alu.setdefault((i, cond), []).append(t)
                if cond is not None and b.code[t].cop in LOADS:
                    load.setdefault((i, cond), []).append(t)
        for cond in {c for _, c in (*alu, *load)}:
            for these, others in ((alu, load), (load, alu)):
                under = [iv for (i, c), ts in these.items() if c == cond for iv in self._intervals(i, ts)]
                other = [iv for (i, c), ts in others.items() if c != cond for iv in self._intervals(i, ts)]
                if under and other:
                    self.m.add_no_overlap(under + other)

    def _hint(self, hint: list, period: int | None):
        """Each start; a modulo template's period (default: the placement's length, a straight
        placement is a template of its length) and copies too: CP-SAT completes a partial hint
        poorly."""
        for var, value in zip(self.start, hint):
            self.m.add_hint(var, value)
        if self.period is not None:
            period = period or max(s + len(b.code) for s, b in zip(hint, self.blocks))
            self.m.add_hint(self.period, period)
            for copies, value in zip(self.early, hint):
                for k, var in enumerate(copies, 1):
                    self.m.add_hint(var, value - k * period)

    def solve(self, hint, seconds: float, workers: int, seed: int, log=None, period=None) -> Placement:
        if hint is not None:
            self._hint(hint, period)
        solver = self.cp.CpSolver()
        solver.parameters.max_time_in_seconds = seconds
        solver.parameters.num_workers = workers
        solver.parameters.random_seed = seed
        if log is not None:
            solver.parameters.log_search_progress = True
            solver.log_callback = log
        status = solver.solve(self.m)
        if status not in (self.cp.OPTIMAL, self.cp.FEASIBLE):
            raise RuntimeError(f"CP-SAT found no placement in {seconds} s ({solver.status_name(status)})")
        return Placement([solver.value(v) for v in self.start], int(solver.objective_value),
                         int(solver.best_objective_bound), status == self.cp.OPTIMAL)


def solve(blocks, *, hint: list | None = None, horizon: int | None = None, seconds: float = 60,
          workers: int = 2, seed: int = 1, log=None, modulo: bool = False,
          period: int | None = None) -> Placement:
    """The shortest placement of ``blocks`` (:func:`.schedule.blocks_of`) CP-SAT finds in
    ``seconds`` with ``workers`` threads, starting from ``hint`` (a placement's starts, e.g. of
    the list scheduler), no longer than ``horizon`` clocks (default: the hint's length, or the
    blocks end to end). ``modulo``: one pose's blocks as a modulo schedule's template, the
    shortest period (``hint`` a template of ``period``, or a straight placement). ``log``: called
    with each line of the solver's log."""
    if horizon is None:
        horizon = sum(len(b.code) for b in blocks) + 1
        if hint is not None:
            horizon = max(s + len(b.code) for s, b in zip(hint, blocks))
    if modulo:
        horizon = 2 * (period or horizon)      # the starts of a pose within two periods
    return _Model(blocks, horizon, modulo).solve(hint, seconds, workers, seed, log, period)
