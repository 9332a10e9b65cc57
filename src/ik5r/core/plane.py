"""The fixed-point solver's rule for the arm's plane near the base axis, in float (bottom layer):
for float64 run on the solver's own input words (``reference.ik(..., approach_plane=
fixed_plane(cfg))``), so that it compares like with like (docs/algorithm.md, "Joint 1 near the
base axis"; the rule itself is ``ik5r.core.ik._plane_direction``)."""

from __future__ import annotations

import numpy as np

from .fxconfig import CHECK_BITS


def fixed_plane(cfg) -> tuple:
    """``approach_plane`` of ``reference.ik`` for a fixed-point config (a FixedConfig): the solver's
    rule for the arm's plane, on float values that are that config's input words."""
    return (cfg.frac_length, cfg.frac_unit, cfg.internal_guard_bits, cfg.width, cfg.round_nearest)


def _magnitude(value, high):
    return np.clip(value, 0, high) - np.clip(value, -high - 1, 0)


def plane_direction(px, py, ax, ay, plane):
    """The fixed-point solver's direction of the arm's plane (docs/algorithm.md, "Joint 1 near the
    base axis"; ``ik._plane_direction``) for float values that are input words of the
    format ``plane`` = (frac_length, frac_unit, guard bits, width, round nearest): its integer
    test and sign, bit for bit, then u + s v 2^(fu - fl) (cm) where near, else u."""
    fl, fu, guard, width, nearest = plane
    words = [np.rint(v * 2.0 ** f).astype(np.int64) for v, f in ((px, fl), (py, fl), (ax, fu), (ay, fu))]
    wpx, wpy, wax, way = words
    high = (1 << (width + guard - 1)) - 1            # the internal word's range
    cross = wpx * way - wpy * wax                    # words: below 2**63 (see ik.py)
    cross = (cross + ((1 << (fu - guard - 1)) if nearest else 0)) >> (fu - guard)
    span = _magnitude(wax << guard, high) + _magnitude(way << guard, high)
    threshold = (span + ((1 << (fu - 2)) if nearest else 0)) >> (fu - 1)
    near = threshold - _magnitude(cross, high) >= 0
    shift = max(0, width + guard - CHECK_BITS)
    opposed = ((wax << guard) >> shift) * (wpx << guard) + ((way << guard) >> shift) * (wpy << guard) < 0
    scale = np.where(near, np.where(opposed, -1.0, 1.0), 0.0) * 2.0 ** (fu - fl)
    return px + scale * ax, py + scale * ay
