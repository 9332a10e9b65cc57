"""Per-arm accuracy records: tool-point error against float64 and C == scalar == vectorised.

    python -m ik5r.tools.arm_accuracy [--arm NAME ...] [--config q32w] [--poses N] [--records DIR]

For each arm of the closed-form family (default: every shipped one) at ``config``: ``poses``
random reachable poses drawn in the joint limits, their float64 branch, the vectorised model's
answer on the quantised pose, and the tool point of that answer against the target
(:func:`ik5r.tools.sweep_error.error_figures`: max and RMS, cm), then the C solver, the scalar
and the vectorised model on random and directed poses, every output field compared
(:func:`ik5r.tools.report.bitaccuracy.software_agreement`). Writes
``<records>/arm_accuracy/<arm>_<config>.json``; the README's per-arm table
(:mod:`ik5r.tools.results_arms`) is generated from these and the synthesis records.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

#: The floor of issue 26: max tool-point error <= 5e-9 x the arm's reach.
ERROR_FLOOR_PER_REACH = 5e-9


def measure(arm, cfg, poses: int, seed: int = 0) -> dict:
    """The record of one arm at one config (see the module docstring)."""
    from ik5r.core.fxconfig import Constants
    from ik5r.firmware_model.poses import concat
    from ik5r.firmware_model.vectors import edge_poses, random_poses

    from .report.bitaccuracy import software_agreement
    from .sweep_error import error_figures

    k = Constants(cfg, arm)
    t0 = time.perf_counter()
    err = error_figures(cfg, poses, seed, arm)
    agreement = software_agreement(k, concat(random_poses(k, max(poses // 8, 1), seed=1), edge_poses(k)))
    differing = sum(sum(p["field_mismatches"].values()) for p in agreement["pairs"])
    reach = arm.reach
    return {
        "arm": arm.name, "arm_sha256": arm.dh_sha256(), "reach_cm": reach, "config": cfg.name,
        "poses": poses, "seed": seed,
        "position_err_max_cm": err["position_err_max_cm"], "position_err_rms_cm": err["position_err_rms_cm"],
        "position_err_max_per_reach": err["position_err_max_cm"] / reach,
        "floor_per_reach": ERROR_FLOOR_PER_REACH,
        "meets_floor": err["position_err_max_cm"] <= ERROR_FLOOR_PER_REACH * reach,
        "joint_err_max_rad": err.get("joint_err_max_rad"),
        "software_agreement": agreement, "software_differing_fields": differing,
        "seconds": round(time.perf_counter() - t0, 2),
    }


def main(argv=None) -> int:
    from ik5r.core.arm import load_arm, shipped_arm_names
    from ik5r.core.chain import closed_form_arm
    from ik5r.core.fxconfig import load_config

    parser = argparse.ArgumentParser(prog="python -m ik5r.tools.arm_accuracy", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--arm", action="append", default=None, help="arm name or TOML (repeat; default: all shipped)")
    parser.add_argument("--config", default="q32w")
    parser.add_argument("--poses", type=int, default=100_000)
    parser.add_argument("--records", default="docs/results/records", help="records folder")
    args = parser.parse_args(argv)
    names = args.arm or [n for n in shipped_arm_names() if closed_form_arm(n) is not None]
    cfg = load_config(args.config)
    out = Path(args.records) / "arm_accuracy"
    out.mkdir(parents=True, exist_ok=True)
    for name in names:
        r = measure(load_arm(name), cfg, args.poses)
        path = out / f"{r['arm']}_{cfg.name}.json"
        path.write_text(json.dumps(r, indent=1, sort_keys=True) + "\n")
        print(f"{r['arm']:14} {cfg.name}: tool point max {r['position_err_max_cm']:.3g} cm "
              f"({r['position_err_max_per_reach']:.3g} x reach {r['reach_cm']:.4g} cm), rms "
              f"{r['position_err_rms_cm']:.3g} cm; C/scalar/vector differing fields {r['software_differing_fields']}"
              f" -> {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
