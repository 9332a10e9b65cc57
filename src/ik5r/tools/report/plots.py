"""Plots of the quantisation report (matplotlib, Agg backend): PNG files written into the report folder.

Each function takes the :class:`~.quantisation.Samples` of a run and the output folder and returns
the PNG's file name (relative to the folder, for the page's ``<img src>``).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .sampling import JOINTS, Samples

#: Scatter / hexbin plots show at most this many poses (a random subset).
MAX_POINTS = 200_000
FLOOR = 1e-18  # errors below this are drawn at it on log axes
COLOURS = {"fixed": "tab:blue", "float32": "tab:orange"}


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, out_dir: Path, name: str) -> str:
    fig.savefig(Path(out_dir) / name, dpi=110, bbox_inches="tight")
    _pyplot().close(fig)
    return name


def _log_bins(*arrays, count=80):
    values = np.concatenate([np.maximum(np.abs(a), FLOOR) for a in arrays])
    lo, hi = math.log10(values.min()), math.log10(values.max())
    if hi - lo < 1e-6:
        lo, hi = lo - 0.5, hi + 0.5
    return np.logspace(lo, hi, count)


def _subset(samples: Samples, seed=12345):
    n = len(samples.q)
    if n <= MAX_POINTS:
        return np.arange(n)
    return np.sort(np.random.default_rng(seed).choice(n, MAX_POINTS, replace=False))


def position_histogram(samples: Samples, out_dir) -> str:
    plt = _pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.8))
    for ax, key, unit in ((axes[0], "position_err", "cm"), (axes[1], "approach_err", "rad")):
        data = getattr(samples, key)
        bins = _log_bins(data["fixed"], data["float32"])
        for solver in ("fixed", "float32"):
            ax.hist(np.maximum(data[solver], FLOOR), bins=bins, histtype="step", lw=1.5,
                    color=COLOURS[solver], label=f"{solver} ({samples.cfg.name})" if solver == "fixed" else solver)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(f"{'position' if unit == 'cm' else 'approach-direction'} error ({unit})")
        ax.set_ylabel("poses")
        ax.grid(alpha=0.3, which="both")
        ax.legend()
    fig.suptitle("Task-space error of FK(solved q) against the target")
    return _save(fig, out_dir, "position_error_hist.png")


def joint_histograms(samples: Samples, out_dir) -> str:
    plt = _pyplot()
    fig, axes = plt.subplots(1, 5, figsize=(17, 3.4), sharey=True)
    lsb = 2.0**-samples.cfg.frac_angle
    for j, (ax, name) in enumerate(zip(axes, JOINTS)):
        fx = samples.joint_err["fixed_vs_exact"][:, j] / lsb
        own = samples.joint_err["fixed_vs_quantised"][:, j] / lsb
        f32 = samples.joint_err["float32_vs_exact"][:, j] / lsb
        bins = _log_bins(fx, own, f32, count=60)
        ax.hist(np.maximum(np.abs(fx), FLOOR), bins=bins, histtype="step", lw=1.5, color=COLOURS["fixed"],
                label="fixed vs f64 exact")
        ax.hist(np.maximum(np.abs(own), FLOOR), bins=bins, histtype="step", lw=1, ls="--", color="tab:green",
                label="fixed vs f64 quantised")
        ax.hist(np.maximum(np.abs(f32), FLOOR), bins=bins, histtype="step", lw=1.5, color=COLOURS["float32"],
                label="float32 vs f64 exact")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(name)
        ax.set_xlabel(f"|error| (LSB = 2^-{samples.cfg.frac_angle} rad)")
        ax.grid(alpha=0.3, which="both")
    axes[0].set_ylabel("poses")
    axes[0].legend(fontsize=7, loc="upper left")
    fig.suptitle("Per-joint error against float64 on the same branch")
    return _save(fig, out_dir, "joint_error_hist.png")


def position_vs_workspace(samples: Samples, out_dir) -> str:
    plt = _pyplot()
    idx = _subset(samples)
    fig, axes = plt.subplots(2, 2, figsize=(11, 7), sharey="row")
    for row, solver in enumerate(("fixed", "float32")):
        err = np.log10(np.maximum(samples.position_err[solver][idx], FLOOR))
        for col, (coord, label) in enumerate(((samples.radius, "reach: distance from base axis (cm)"),
                                              (samples.height, "height z (cm)"))):
            ax = axes[row, col]
            hb = ax.hexbin(coord[idx], err, gridsize=70, bins="log", mincnt=1, cmap="viridis")
            ax.set_xlabel(label)
            if col == 0:
                ax.set_ylabel(f"log10 position error, {solver} (cm)")
            fig.colorbar(hb, ax=ax, label="poses")
    fig.suptitle(f"Position error across the workspace ({len(idx):,} of {len(samples.q):,} poses)")
    return _save(fig, out_dir, "position_error_workspace.png")


def joint_vs_sin_q3(samples: Samples, out_dir, conditioning: dict) -> str:
    plt = _pyplot()
    idx = _subset(samples)
    idx = idx[: min(len(idx), 50_000)] if len(idx) > 50_000 else idx
    s3 = np.maximum(samples.sin_q3[idx], FLOOR)
    fig, axes = plt.subplots(1, 3, figsize=(16, 4.2), sharey=True)
    arm = samples.arm
    dw = conditioning["max_input_error"]["wrist_centre_cm"]
    h_u = conditioning["lsb"]["unit"]
    grid = np.logspace(math.log10(s3.min()), 0, 50)
    bounds = {"q2": dw / (arm.a[1] * grid),
              "q3": (arm.a[1] + arm.a[2]) * dw / (arm.a[1] * arm.a[2] * grid) + h_u / 2 / grid}
    for ax, name in zip(axes, ("q2", "q3", "q4")):
        j = JOINTS.index(name)
        for comp, colour, label in (("float32_vs_exact", COLOURS["float32"], "float32 vs f64 exact"),
                                    ("fixed_vs_exact", COLOURS["fixed"], "fixed vs f64 exact"),
                                    ("fixed_vs_quantised", "tab:green", "fixed vs f64 quantised")):
            ax.scatter(s3, np.maximum(np.abs(samples.joint_err[comp][idx, j]), FLOOR), s=2, alpha=0.3,
                       color=colour, label=label, rasterized=True)
        if name in bounds:
            ax.plot(grid, bounds[name], "k--", lw=1, label="first-order fixed input bound"
                    + (" + c3 rounding" if name == "q3" else ""))
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("|sin q3|")
        ax.set_title(name)
        ax.grid(alpha=0.3, which="both")
    axes[0].set_ylabel("|joint error| (rad)")
    axes[0].set_ylim(bottom=max(FLOOR, 1e-3 * 2.0**-samples.cfg.frac_angle))
    axes[0].legend(fontsize=7, markerscale=4, loc="lower left")
    fig.suptitle(f"Joint error against |sin q3| ({len(idx):,} poses): 1/|sin q3| near the straight/folded elbow")
    return _save(fig, out_dir, "joint_error_vs_sin_q3.png")


def approach_vs_radius(samples: Samples, out_dir) -> str:
    plt = _pyplot()
    idx = _subset(samples)
    idx = idx[:50_000]
    rho = np.maximum(samples.radius[idx], FLOOR)
    fig, ax = plt.subplots(figsize=(7, 4.2))
    for solver in ("float32", "fixed"):
        ax.scatter(rho, np.maximum(samples.approach_err[solver][idx], FLOOR), s=2, alpha=0.3,
                   color=COLOURS[solver], label=solver, rasterized=True)
    grid = np.logspace(math.log10(rho.min()), math.log10(rho.max()), 50)
    h_l = 2.0**-samples.cfg.frac_length
    ax.plot(grid, math.sqrt(2) / 2 * h_l / grid, "k--", lw=1, label="fixed q1 input bound (√2/2 LSB_length)/ρ")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_ylim(bottom=1e-12)
    ax.set_xlabel("ρ: distance of the tool point from the base axis (cm)")
    ax.set_ylabel("approach-direction error (rad)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8, markerscale=4, loc="upper right")
    ax.set_title(f"Approach error against ρ ({len(idx):,} poses): q1 is conditioned by 1/ρ")
    return _save(fig, out_dir, "approach_error_vs_radius.png")
