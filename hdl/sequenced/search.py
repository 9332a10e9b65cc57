"""A longer search for the order in which the scheduler places a program's blocks, run offline
and kept (:mod:`.hints`)::

    python -m ik5r.hdl.sequenced.search --config q32w --poses 2 --evaluations 200000
    python -m ik5r.hdl.sequenced.search --renew     # after a change of the lowering

The scheduler's climb (:func:`.schedule.climbed`) stops where no single priority step and no swap
of two priorities shortens the program. From there a (1 + 1) evolutionary search moves one to
four priorities or swaps two, at random, and keeps the change when the program is no longer
(equal ones too: the search drifts across the plateaus of equal length); the climb then runs
again from the order found. It takes tens of
thousands of list schedulings, minutes, too long for every compile: its order is written to
``schedules/<fingerprint>.json`` with the design point and the lengths, and every compile of the
same blocks uses it. Deterministic: the same seed and count of evaluations give the same order.
``--renew`` searches again, with the same evaluations and seed, for each kept order whose blocks
no design point has any more, and removes the old file.

``--cp-sat SECONDS`` then hands the placement to a constraint solver (:mod:`.cpsat`, OR-Tools'
CP-SAT): the blocks' starts as variables of one model, the list scheduler's placement its first
solution. A shorter placement is kept with its starts (a compile places each block no earlier,
which gives that placement back), and the solver's proven lower bound on the length with it: how
much shorter any placement on these units could be. Not deterministic (threads and a time
limit): the kept file is the record, and a run again starts from it where it is shorter.

``--modulo SECONDS`` instead places one pose's blocks as the template of a modulo schedule of the
two-pose program (:mod:`.modulo`: a pose every period, running on into the next run), by the
constraint solver from the one-pose program's placement or the kept template, and keeps it in
``schedules/modulo/<fingerprint of the two-pose blocks>.json`` where its two periods are shorter
than the kept template's and the straight two-pose program's::

    python -m ik5r.hdl.sequenced.search --config q32w --wide-product --modulo 600
"""

from __future__ import annotations

import argparse
import json
import random
import sys
from pathlib import Path

from ik5r.core.arm import load_arm
from ik5r.core.fxconfig import constants, load_config

from . import cpsat, hints
from .hints import fingerprint
from .modulo import cyclic_code, two_pose_starts
from .program import POSES, program_blocks
from .schedule import blocks_of, climbed, placed

__all__ = ["evolve", "search_point", "modulo_point", "renew", "main"]

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
    """A kept order's JSON: a key a line, the priorities (and starts) on one each."""
    lists = [key for key in ("priorities", "starts") if key in kept]
    head = json.dumps({key: value for key, value in kept.items() if key not in lists}, indent=1)
    tail = ",\n".join(f' "{key}": {json.dumps(kept[key])}' for key in lists)
    return f'{head[:-2]},\n{tail}\n}}\n'


#: What a kept order records of its design point, and searches again with (:func:`renew`);
#: ``cp_sat_seconds`` 0 (or absent): no constraint solver.
POINT_KEYS = ("config", "arm", "poses", "wide_product", "evaluations", "seed", "cp_sat_seconds")


def _blocks(point: dict):
    k = constants(load_config(point["config"]), load_arm(point["arm"]))
    _, codes, after = program_blocks(k, point["wide_product"], point["poses"])
    return k, blocks_of(codes, after)


def _starts(table, blocks) -> list:
    start = {id(b): t for b, t in table.placed}
    return [start[id(b)] for b in blocks]


def _solved(blocks, table, order: tuple, seconds: float, seed: int, log=None) -> dict:
    """The constraint solver's placement from the list scheduler's ``table`` (of ``order``:
    priorities, and starts or None), kept only where shorter: {priorities, starts, clocks,
    cp_sat_bound}."""
    found = cpsat.solve(blocks, hint=_starts(table, blocks), seconds=seconds, workers=WORKERS, seed=seed, log=log)
    kept = {"clocks": len(table), "cp_sat_bound": found.bound, "priorities": order[0]}
    kept |= {"starts": order[1]} if order[1] else {}
    if found.clocks < len(table):
        order = [found.clocks - s for s in found.starts]    # earliest first
        if len(placed(blocks, order, found.starts)) != found.clocks:
            raise AssertionError("the list scheduler did not reproduce the solver's placement")
        kept.update(clocks=found.clocks, priorities=order, starts=found.starts)
    return kept


#: Threads of the constraint solver.
WORKERS = 2


def search_point(point: dict, progress=None, log=None) -> Path:
    """The order of design point ``point`` (:data:`POINT_KEYS`; ``arm`` None: the arm of record)
    searched and kept, then placed by the constraint solver for ``cp_sat_seconds`` if given;
    returns its file."""
    k, blocks = _blocks(point)
    table, prio = climbed(blocks)
    _, prio = evolve(blocks, prio, evaluations=point["evaluations"], seed=point["seed"], progress=progress)
    # The climb again from the search's order: a last step or swap the mutations did not try.
    polished, prio = climbed(blocks, prio)
    kept = {"clocks": len(polished), "priorities": prio}
    if point.get("cp_sat_seconds"):
        # From the shorter of this search's placement and the one kept: a run again goes on
        # from where the last one stopped (the solver's runs differ, threads and time limits).
        order, before = (prio, None), hints.hint(blocks)
        if before is not None and len(earlier := placed(blocks, *before)) < len(polished):
            polished, order = earlier, before
        kept = _solved(blocks, polished, order, point["cp_sat_seconds"], point["seed"], log)
    hints.SCHEDULES.mkdir(exist_ok=True)
    path = hints.SCHEDULES / f"{fingerprint(blocks)}.json"
    path.write_text(kept_text({**point, "config": k.cfg.name, "arm": k.arm.name,
                               "climb_clocks": len(table), **kept}))
    return path


def renew(progress=None) -> list[tuple[Path, Path]]:
    """Each kept order whose blocks no design point has any more (the lowering changed) searched
    again for its design point, with its count of evaluations and seed; the old file removed.
    Returns (old, new) per order renewed."""
    renewed = []
    for path in hints.order_files():
        kept = json.loads(path.read_text())
        point = {key: kept[key] for key in POINT_KEYS if key in kept}
        if fingerprint(_blocks(point)[1]) != path.stem:
            new = search_point(point, progress)
            path.unlink()
            renewed.append((path, new))
    return renewed


def modulo_point(point: dict, seconds: float, log=None) -> tuple[Path | None, cpsat.Placement]:
    """A modulo schedule (:mod:`.modulo`) of the two-pose program of design point ``point``: its
    template, one pose's blocks, placed by the constraint solver for ``seconds`` from the kept
    template (else from the one-pose program's placement), kept where its two periods are
    shorter than the kept template's and the straight two-pose program. Returns its file (None
    if it was not kept) and the solver's result."""
    k = constants(load_config(point["config"]), load_arm(point["arm"]))
    _, codes, after = program_blocks(k, point["wide_product"], 2)
    _, one, _ = program_blocks(k, point["wide_product"], 1)
    blocks, template = blocks_of(codes, after), blocks_of(one)
    kept = hints.modulo_hint(blocks)
    if kept is None:
        order = hints.hint(template)
        table = placed(template, *order) if order else climbed(template)[0]
        hint, period = _starts(table, template), None
    else:
        period, hint = kept
    found = cpsat.solve(template, hint=hint, seconds=seconds, workers=WORKERS, seed=point["seed"],
                        log=log, modulo=True, period=period)
    straight = len(placed(blocks, *hints.hint(blocks))) if hints.hint(blocks) else len(climbed(blocks)[0])
    if 2 * found.clocks >= min(straight, 2 * (period or straight)):
        return None, found
    cyclic_code(codes, after, two_pose_starts(found.starts, found.clocks), 2 * found.clocks, 2)   # checks it
    path = hints.SCHEDULES / "modulo" / f"{fingerprint(blocks)}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"config": k.cfg.name, "arm": k.arm.name, "poses": 2,
                                "wide_product": point["wide_product"], "seed": point["seed"],
                                "cp_sat_seconds": seconds, "period": found.clocks,
                                "cp_sat_bound": found.bound, "straight_clocks": straight,
                                "starts": found.starts}, indent=1) + "\n")
    return path, found


def _args(argv):
    parser = argparse.ArgumentParser(prog="python -m ik5r.hdl.sequenced.search", description=__doc__.split("\n\n")[0])
    parser.add_argument("--config", default="q32w", help="fixed-point config (a shipped name or a TOML)")
    parser.add_argument("--arm", default=None, help="arm (a shipped name or a TOML; default: the arm of record)")
    parser.add_argument("--poses", type=int, choices=POSES, default=1)
    parser.add_argument("--wide-product", action="store_true")
    parser.add_argument("--evaluations", type=int, default=100_000)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--cp-sat", type=float, default=0, metavar="SECONDS",
                        help="then place the blocks with OR-Tools' CP-SAT for SECONDS (a proven "
                             "lower bound on the length too)")
    parser.add_argument("--modulo", type=float, default=0, metavar="SECONDS",
                        help="instead, a modulo schedule of the two-pose program by CP-SAT for SECONDS")
    parser.add_argument("--renew", action="store_true",
                        help="search again every kept order no design point uses any more (ignores the options above)")
    return parser.parse_args(argv)


def _progress(done, length):
    print(f"\r{done:,} evaluations: {length} clocks", end="", file=sys.stderr)


def _solver_progress(line: str):
    """CP-SAT's log lines of a new best placement or bound (``#3  12.5s best:1015 next:[941,1014]``)."""
    if line.startswith("#") and "best:" in line:
        print("\rCP-SAT " + " ".join(line.split()[1:4]) + "        ", end="", file=sys.stderr)


def main(argv=None) -> int:
    args = _args(argv)
    progress = _progress if sys.stderr.isatty() else None
    if args.renew:
        for old, new in renew(progress):
            print(f"{old.name} -> {new}: {json.loads(new.read_text())['clocks']} clocks")
        return 0
    if args.modulo:
        point = {"config": args.config, "arm": args.arm, "wide_product": args.wide_product, "seed": args.seed}
        path, found = modulo_point(point, args.modulo, _solver_progress if progress else None)
        print(f"{path or 'not kept'}: a pose every {found.clocks} clocks (CP-SAT's bound: "
              f"{found.bound}){'' if path else ', not shorter than the kept template or the two-pose program'}")
        return 0
    path = search_point({"config": args.config, "arm": args.arm, "poses": args.poses,
                         "wide_product": args.wide_product, "evaluations": args.evaluations,
                         "seed": args.seed, "cp_sat_seconds": args.cp_sat}, progress,
                        _solver_progress if progress else None)
    kept = json.loads(path.read_text())
    bound = f", at least {kept['cp_sat_bound']} by CP-SAT" if "cp_sat_bound" in kept else ""
    print(f"{path}: {kept['clocks']} clocks (climb {kept['climb_clocks']}{bound})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
