"""A longer search for the order in which the scheduler places a program's blocks, run offline
and kept (:mod:`.hints`)::

    python -m ik5r.hdl.sequenced.search --config q32w --poses 2 --evaluations 300000

The scheduler's climb (:func:`.schedule.climbed`) stops where no single priority step and no swap
of two priorities shortens the program. From there a (1 + 1) evolutionary search moves one to
four priorities or swaps two, at random, and keeps the change when the program is no longer
(equal ones too: the search drifts across the plateaus of equal length); the climb then runs
again from the order found. It takes tens of
thousands of list schedulings, minutes, too long for every compile: its order is written to
``schedules/<fingerprint>.json`` with the design point and the lengths, and every compile of the
same blocks uses it. Deterministic: the same seed and count of evaluations give the same order.
"""

from __future__ import annotations

import argparse
import json
import random
import sys
import time

from ik5r.core.arm import load_arm
from ik5r.core.fxconfig import constants, load_config

from .hints import SCHEDULES, fingerprint
from .program import POSES, program_blocks
from .schedule import blocks_of, climbed, placed

__all__ = ["evolve", "main"]

#: Priority moves of the search (the climb's steps, and smaller ones).
MOVES = (-400, -200, -100, -50, -20, -5, 5, 20, 50, 100, 200, 400)


def _mutant(prio: list, rng: random.Random) -> list:
    """``prio`` with one to four of its inner blocks' priorities moved or swapped (the input and
    output blocks stay first and last)."""
    trial = list(prio)
    for _ in range(rng.choice((1, 1, 2, 2, 3, 4))):
        i = rng.randrange(1, len(prio) - 1)
        if rng.random() < 0.5:
            trial[i] += rng.choice(MOVES)
        else:
            j = rng.randrange(1, len(prio) - 1)
            trial[i], trial[j] = trial[j], trial[i]
    return trial


def evolve(blocks, prio: list, *, evaluations: int, seed: int = 1, progress=None) -> tuple[int, list]:
    """The shortest program's length and priorities found in ``evaluations`` list schedulings
    from ``prio``; ``progress(done, length)`` after each shorter one and every 1,000."""
    rng = random.Random(seed)
    current, length = list(prio), len(placed(blocks, prio))
    best = (length, list(prio))
    for done in range(1, evaluations + 1):
        trial = _mutant(current, rng)
        trial_length = len(placed(blocks, trial))
        if trial_length <= length:
            current, length = trial, trial_length
            if length < best[0]:
                best = (length, list(trial))
                progress and progress(done, length)
        if progress and done % 1000 == 0:
            progress(done, best[0])
    return best


def kept_text(kept: dict) -> str:
    """A kept order's JSON: a key a line, the priorities on one."""
    head = json.dumps({key: value for key, value in kept.items() if key != "priorities"}, indent=1)
    return f'{head[:-2]},\n "priorities": {json.dumps(kept["priorities"])}\n}}\n'


def _args(argv):
    parser = argparse.ArgumentParser(prog="python -m ik5r.hdl.sequenced.search", description=__doc__.split("\n\n")[0])
    parser.add_argument("--config", default="q32w", help="fixed-point config (a shipped name or a TOML)")
    parser.add_argument("--arm", default=None, help="arm (a shipped name or a TOML; default: the arm of record)")
    parser.add_argument("--poses", type=int, choices=POSES, default=1)
    parser.add_argument("--wide-product", action="store_true")
    parser.add_argument("--evaluations", type=int, default=100_000)
    parser.add_argument("--seed", type=int, default=1)
    return parser.parse_args(argv)


def main(argv=None) -> int:
    args = _args(argv)
    k = constants(load_config(args.config), load_arm(args.arm))
    _, codes, after = program_blocks(k, args.wide_product, args.poses)
    blocks = blocks_of(codes, after)
    start = time.monotonic()
    table, prio = climbed(blocks)
    print(f"climb: {len(table)} clocks ({time.monotonic() - start:.0f} s)", file=sys.stderr)

    def progress(done, length):
        print(f"\r{done:,} of {args.evaluations:,} evaluations: {length} clocks", end="", file=sys.stderr)

    terminal = sys.stderr.isatty()
    length, prio = evolve(blocks, prio, evaluations=args.evaluations, seed=args.seed,
                          progress=progress if terminal else None)
    if terminal:
        print(file=sys.stderr)
    # The climb again from the search's order: a last step or swap the mutations did not try.
    polished, prio = climbed(blocks, prio)
    length = len(polished)
    SCHEDULES.mkdir(exist_ok=True)
    path = SCHEDULES / f"{fingerprint(blocks)}.json"
    path.write_text(kept_text({
        "config": k.cfg.name, "arm": k.arm.name, "poses": args.poses, "wide_product": args.wide_product,
        "climb_clocks": len(table), "clocks": length, "evaluations": args.evaluations, "seed": args.seed,
        "priorities": prio}))
    print(f"{path}: {length} clocks (climb {len(table)})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
