"""``ik5r board``: a bitstream of the IK core on a framed UART link, for iCEBreaker or ULX3S.

Boards: ``icebreaker`` (iCE40 UP5K, 12 MHz, the compact core behind its word-serial wrapper),
``ulx3s-25f`` (ECP5-25F, 25 MHz, the compact core), ``ulx3s-85f`` (ECP5-85F, 25 MHz, the
pipelined core). The UART is the board's USB serial port (8N1, default 3 Mbaud); the protocol is
docs/protocol.md. Writes ``ik5r_board.bin`` (iCE40) or ``ik5r_board.bit`` (ECP5) and
``record.json`` into -o DIR (default ``build/board/BOARD``); ``--record`` also stores the record
in docs/results/records/board/. Flash with ``openFPGALoader -b icebreaker DIR/ik5r_board.bin``
or ``openFPGALoader -b ulx3s DIR/ik5r_board.bit``, then run ``ik5r solve POSES.csv --solver board
--port /dev/ttyUSB1``. Needs the 'synth' extra (amaranth-boards and the YoWASP tools).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from ik5r.core.fxconfig import DEFAULT_CONFIG
from ik5r.core.modes import BOARD_CORES
from ik5r.tools import cliopts


def register(subparsers) -> None:
    from ik5r.tools.board import BOARDS

    parser = subparsers.add_parser("board", help="bitstream of the IK core on a UART link for a real board",
                                   description=__doc__)
    parser.add_argument("--board", choices=tuple(BOARDS), required=True, help="the board")
    parser.add_argument("--config", default=None, metavar="CFG",
                        help=f"fixed-point config TOML or shipped name (default: {DEFAULT_CONFIG})")
    parser.add_argument("--arm", default=None, metavar="ARM.toml",
                        help="arm description TOML (default: the arm of record)")
    parser.add_argument("--baud", type=int, default=None, help="UART baud rate (default: 3000000)")
    parser.add_argument("--core", choices=BOARD_CORES, default=None,
                        help="the IK core (default: the board's)")
    parser.add_argument("--seed", type=int, default=1, help="nextpnr seed (default: 1)")
    parser.add_argument("-o", "--output", default=None, metavar="DIR",
                        help="build folder (default: build/board/BOARD)")
    parser.add_argument("--record", action="store_true",
                        help="also write the record to docs/results/records/board/")
    parser.set_defaults(run=run)


def run(args) -> int:
    from ik5r.core.arm import load_arm
    from ik5r.core.fxconfig import constants, load_config
    from ik5r.tools.board import RECORDS, build
    from ik5r.tools.synth_progress import StatusLine

    k = constants(load_config(args.config), load_arm(args.arm))
    out = Path(args.output or f"build/board/{args.board}")
    # Where nextpnr is, in one line rewritten in place: on a terminal only.
    status = StatusLine(sys.stderr) if cliopts.show_progress(args) else None
    try:
        record = build(args.board, k, baud=args.baud, out=out, seed=args.seed, core=args.core,
                       progress=status and status.show)
    finally:
        if status:
            status.clear()
    text = json.dumps(record, indent=2, sort_keys=True) + "\n"
    (out / "record.json").write_text(text)
    if args.record:
        RECORDS.mkdir(parents=True, exist_ok=True)
        (RECORDS / f"{args.board}_{record['core']}_{record['config']}.json").write_text(text)
    met = "met" if record["timing_met"] else "NOT met"
    print(f"{args.board}: {out / record['bitstream']} ({record['bitstream_bytes']} bytes), "
          f"Fmax {record['fmax_mhz']} MHz against {record['clock_mhz']:g} MHz: timing {met}; "
          f"{record['baud']} baud, {record['line_poses_per_s']:g} poses/s at line rate")
    return 0 if record["timing_met"] else 1
