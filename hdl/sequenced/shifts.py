"""The accumulator's shifts right: three amounts per program (:data:`.isa.SHIFTS`), chosen to do
the program's shifts in the fewest clocks (:func:`acc_shifts_for`); a shift by n as the fewest
of them (:func:`shift_ops`)."""

from __future__ import annotations

import itertools

from .isa import SHIFTS

__all__ = ["acc_shifts_for", "shift_ops"]


def shift_ops(n: int, sizes: tuple) -> list:
    """The fewest shifts of ``sizes`` (bits by op of :data:`~.isa.SHIFTS`) that add up to ``n``,
    largest first, or None if none do."""
    best: list = [[]] + [None] * n      # best[m]: the fewest sizes adding up to m
    for m in range(1, n + 1):
        ways = [best[m - s] + [s] for s in sizes if s <= m and best[m - s] is not None]
        best[m] = min(ways, key=len, default=None)
    if best[n] is None:
        return None
    return sorted(best[n], reverse=True)


def acc_shifts_for(amounts: dict) -> tuple:
    """The accumulator's three shift amounts for a program shifting by ``amounts`` (bits ->
    times): the fewest shift ops in all, then the smallest amounts. The three are inputs of
    the accumulator's result mux whatever they are, so each program picks its own."""
    top = max(amounts, default=1)
    best, cost = (1, 4, 16), None
    for sizes in itertools.combinations(range(1, top + 1), len(SHIFTS)):
        fewest = [0] + [top + 1] * top     # fewest[m]: shifts adding up to m (top + 1: none)
        for m in range(1, top + 1):
            fewest[m] = min([fewest[m - s] + 1 for s in sizes if s <= m], default=top + 1)
        total = sum(times * fewest[n] for n, times in amounts.items())
        if all(fewest[n] <= top for n in amounts) and (cost is None or total < cost):
            best, cost = sizes, total
    return best
