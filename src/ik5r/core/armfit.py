"""Does a config's length format hold an arm? The bounds of every length the IK carries.

Every length of the fixed-point IK (the input position, the wrist centre, the link constants, the
shoulder's a2 + a3 cos q3) is a word of ``frac.length`` fraction bits, so its magnitude must stay
below ``2**m`` cm, ``m = width - 1 - frac.length`` (the internal format adds fraction bits only:
the same ``m``). Squared lengths are exact products in twice the width (below ``2**2m``). For
every pose the arm can reach these quantities are bounded by the arm's numbers alone
(:func:`length_bounds`); a config is refused for an arm when one bound, with
:data:`HEADROOM` for the rounding of inputs and the reach tolerance, passes its limit: such a core
would answer ``saturated`` or ``unreachable`` where the arm reaches.

:func:`integer_bits_for` is the rule ``ik5r config --arm`` writes configs by: the magnitude bits
the largest bound needs, one guard bit above them (as the shipped configs have for the arm of
record: its bounds need 6 bits, the configs carry 7) and the sign.
"""

from __future__ import annotations

import math

from .arm import Arm
from .errors import InputError

#: Relative headroom over each bound (inputs rounded to their LSB, the reach tolerance).
HEADROOM = 2.0 ** -6
#: Magnitude bits ``ik5r config --arm`` adds above the largest bound.
GUARD_BITS = 1


def length_bounds(arm: Arm) -> list[tuple[str, float, int]]:
    """(quantity, bound in cm, power of the bound: 1 a length, 2 a squared length) over every
    pose the arm reaches. The tool point is at most a1 + a2 + a3 + |(a4, d5)| from the joint-1
    axis and |d1| + a2 + a3 + |(a4, d5)| from the base plane; the wrist centre at most a2 + a3
    from the shoulder (so are a2 + a3 cos q3 and the shoulder's atan2 operands)."""
    a1, a2, a3, a4, _ = (abs(v) for v in arm.a)
    d1, d5 = abs(arm.d[0]), abs(arm.d[4])
    wrist = math.hypot(a4, d5)
    return [
        ("tool point x, y (a1 + a2 + a3 + |(a4, d5)|)", a1 + a2 + a3 + wrist, 1),
        ("tool point z (|d1| + a2 + a3 + |(a4, d5)|)", d1 + a2 + a3 + wrist, 1),
        ("wrist centre and a2 + a3 cos q3 (a2 + a3)", a2 + a3, 1),
        ("squared wrist distance ((a2 + a3)^2)", (a2 + a3) ** 2, 2),
        ("link constants (largest of a1, a2, a4, d1, d5)", max(a1, a2, a4, d1, d5), 1),
    ]


def magnitude_bits(bound: float, power: int) -> int:
    """Integer bits (above the binary point, no sign) a length of this bound needs; for a squared
    length (``power`` 2) the bits of the length it is the square of."""
    length = bound ** (1.0 / power) * (1 + HEADROOM)
    return max(0, math.ceil(math.log2(length))) if length > 0 else 0


def needed_magnitude_bits(arm: Arm) -> tuple[int, str, float]:
    """(the most magnitude bits any bound needs, its quantity, its bound)."""
    return max(((magnitude_bits(b, p), q, b) for q, b, p in length_bounds(arm)), key=lambda t: t[0])


def integer_bits_for(arm: Arm) -> int:
    """Bits above the length format's binary point, sign included, by the shipped configs' rule."""
    return needed_magnitude_bits(arm)[0] + GUARD_BITS + 1


def check_fits(cfg, arm: Arm) -> None:
    """InputError (one line: arm, quantity, bound, limit, smallest width that fits) unless the
    config's length format holds every bound of :func:`length_bounds`."""
    m = cfg.width - 1 - cfg.frac_length
    for quantity, bound, power in length_bounds(arm):
        need = magnitude_bits(bound, power)
        if need > m:
            unit = "cm" if power == 1 else "cm^2"
            width = cfg.frac_length + 1 + need
            fits = (f"smallest width that fits: {width}" if width <= 32 else
                    f"no width up to 32 fits with frac.length {cfg.frac_length}")
            raise InputError(
                arm.source, f"arm {arm.name} does not fit config {cfg.name}: {quantity} reaches "
                f"{bound:.4g} {unit}, the format holds {2.0 ** (m * power):g} {unit} (frac.length "
                f"{cfg.frac_length} in {cfg.width} bits); {fits} (or fewer fraction bits: "
                f"ik5r config --arm {arm.name} --width {cfg.width} -o FILE)")
