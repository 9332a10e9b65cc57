"""``ik5r arms``: the shipped arms (``src/ik5r/data/arms/``): name, joints, family, reach, source.

``closed form`` arms (the 5R family of the arm of record) go through every fixed-point command
(``--arm NAME``: ``verilog``, ``sim``, ``synth``, ``firmware``, ``solve --solver fixed|c|rv32``);
the others through ``solve --solver numeric`` and ``fk``. Reach: the closed-form bound a1 + a2 + a3
+ |(a4, d5)| (cm), for the others the sum of every |a|, |d| and the tool offset.
"""

from __future__ import annotations


def register(subparsers) -> None:
    parser = subparsers.add_parser("arms", help="list the shipped arms (name, family, reach, source)",
                                   description=__doc__)
    parser.set_defaults(run=run)


def source_line(path) -> str:
    """Where an arm file's numbers come from: its ``# Source:`` line, else its first comment line."""
    comments = [line.lstrip("# ").strip() for line in path.read_text().splitlines() if line.startswith("#")]
    return next((c for c in comments if c.startswith("Source:")), comments[0] if comments else "")


def run(args) -> int:
    from ik5r.core.arm import arms_dir, shipped_arm_names
    from ik5r.core.chain import closed_form_arm, load_chain

    rows = []
    for name in shipped_arm_names():
        path = arms_dir() / f"{name}.toml"
        arm, chain = closed_form_arm(path), load_chain(path)
        reach = arm.reach if arm is not None else chain.reach
        rows.append((name, str(chain.n), "closed form" if arm is not None else "numeric", f"{reach:.2f}",
                     source_line(path)))
    header = ("arm", "joints", "solver", "reach cm", "source")
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(header[:-1])]
    for row in (header, *rows):
        print("  ".join(c.ljust(w) for c, w in zip(row[:-1], widths)) + "  " + row[-1])
    return 0
