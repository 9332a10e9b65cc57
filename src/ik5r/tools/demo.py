"""make demo: the main job of ik5r, end to end, in a few minutes: 'ik5r report --hdl' with the
demo's sizes (the IK core on --poses poses under cocotb, the quantisation figures on
--report-vectors poses) into build/report/, and its summary on the terminal.

    python -m ik5r.tools.demo [--config q32w] [--arm NAME|ARM.toml] [--poses 10000] [--simulator verilator]

``make demo ARM=NAME`` builds and simulates the cores of that arm (``ik5r arms`` lists the
shipped ones); the report names its arm.
"""

from __future__ import annotations

import argparse
import sys
import time

from ik5r.core.fxconfig import DEFAULT_CONFIG


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m ik5r.tools.demo", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--config", default=DEFAULT_CONFIG)
    parser.add_argument("--arm", default=None, help="arm name or TOML (default: the arm of record, hu-5r)")
    parser.add_argument("--poses", type=int, default=10_000, help="random poses through the HDL core")
    parser.add_argument("--block-vectors", type=int, default=5_000, help="random vectors per block")
    parser.add_argument("--report-vectors", type=int, default=1_000_000, help="poses of the quantisation report")
    parser.add_argument("--simulator", default="verilator", choices=("icarus", "verilator"))
    parser.add_argument("-o", "--output", default="build")
    args = parser.parse_args(argv)

    from .cli import main as cli

    t0 = time.perf_counter()
    arm = [] if not args.arm else ["--arm", args.arm]
    status = cli(["report", "--hdl", "--config", args.config, *arm, "--vectors", str(args.report_vectors),
                  "--hdl-poses", str(args.poses), "--block-vectors", str(args.block_vectors),
                  "--simulator", args.simulator, "-o", f"{args.output}/report"])
    if args.arm:
        print(f"demo arm: {args.arm}")
    print(f"demo wall time: {time.perf_counter() - t0:.0f} s")
    return status


if __name__ == "__main__":
    sys.exit(main())
