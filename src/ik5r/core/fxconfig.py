"""The fixed-point configuration: one TOML, the single source of truth.

The C header (``ik5r.firmware_model.codegen``), the bit-accurate models (``ik5r.firmware_model.model``,
``ik5r.firmware_model.vector``) and the Amaranth HDL (``ik5r.hdl``) all take their widths, fraction bits,
iteration counts, rounding and every derived integer constant from :class:`Constants`, so they
cannot drift apart.

Formats: every word is a signed two's-complement integer of ``width`` bits; a value ``v`` of a
quantity with ``n`` fraction bits stands for ``v * 2**-n`` (Q m.n with m + n = width). With
``ik.internal_guard_bits`` = G > 0 the IK runs on the internal format :meth:`FixedConfig.internal`
(G more bits of width, of every fraction and of CORDIC iterations), whose constants are
``Constants.internal``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path

from . import status as st
from .arm import Arm, load_arm
from .armfit import check_fits
from .errors import InputError, read_toml

MAX_WIDTH = 32
#: The shipped config used when none is named: 32-bit words on a 38-bit internal format, the one
#: that meets the joint-accuracy floor near the singular elbow (docs/algorithm.md).
DEFAULT_CONFIG = "q32w"
#: Fraction bits of the CORDIC gain-compensation factor 1/K (stored below 2**31) in every word
#: config; an internal format wider than 32 bits uses width - 1 (``Constants.inv_gain_frac``).
INV_GAIN_FRAC = 31
#: Width of the mantissa of a constant multiplier (fits a signed 32-bit word) in every word config;
#: an internal format wider than 32 bits uses width - 1 (``Constants.const_mant_bits``).
CONST_MANT_BITS = 31
#: Width of the check words of the orientation checks (``Constants.check_shift``): one 17 x 17
#: product each, whatever the word width.
CHECK_BITS = 17


@dataclass(frozen=True)
class FixedConfig:
    name: str
    width: int
    frac_length: int
    frac_unit: int
    frac_angle: int
    iterations: int
    guard_bits: int
    angle_guard_bits: int
    rounding: str
    singular_sin_q3: float
    # Extra fraction bits of every quantity inside the IK (0: the IK runs on the words themselves).
    internal_guard_bits: int = 0
    source: str = "<config>"
    # c3 beyond +-1 by at most this: singular_elbow (straight/folded), not unreachable. None: the
    # default of the format, 2**(2 - frac_length) (a few position LSBs of rounding).
    reach_tolerance: float | None = None
    # Off-plane approach (sine) and n, o, a frame error above this: bad_orientation.
    orientation_tolerance: float = 1e-3

    @property
    def reach_tol(self) -> float:
        """The reach tolerance in force (``reach_tolerance`` or the format's default)."""
        return 2.0 ** (2 - self.frac_length) if self.reach_tolerance is None else self.reach_tolerance

    @property
    def round_nearest(self) -> bool:
        return self.rounding == "nearest"

    def to_toml(self) -> str:
        return (
            f'name = "{self.name}"\nwidth = {self.width}\n\n[frac]\nlength = {self.frac_length}\n'
            f"unit = {self.frac_unit}\nangle = {self.frac_angle}\n\n[cordic]\n"
            f"iterations = {self.iterations}\nguard_bits = {self.guard_bits}\n"
            f"angle_guard_bits = {self.angle_guard_bits}\n\n[ik]\n"
            f'rounding = "{self.rounding}"\nsingular_sin_q3 = {self.singular_sin_q3!r}\n'
            f"internal_guard_bits = {self.internal_guard_bits}\n"
            + ("" if self.reach_tolerance is None else f"reach_tolerance = {self.reach_tolerance!r}\n")
            + f"orientation_tolerance = {self.orientation_tolerance!r}\n"
        )

    def internal(self) -> FixedConfig:
        """The format the IK runs on: ``internal_guard_bits`` more fraction bits in every quantity
        (and as many more bits of word width and CORDIC iterations). Itself when that is 0."""
        g = self.internal_guard_bits
        if g == 0:
            return self
        return replace(self, name=f"{self.name}-internal", width=self.width + g,
                       reach_tolerance=self.reach_tol, frac_length=self.frac_length + g, frac_unit=self.frac_unit + g,
                       frac_angle=self.frac_angle + g, iterations=self.iterations + g,
                       internal_guard_bits=0)


_SCHEMA = {
    # key path: (type, lower, upper) -- upper may depend on width, checked after.
    ("width",): (int, 8, MAX_WIDTH),
    ("frac", "length"): (int, 1, MAX_WIDTH - 2),
    ("frac", "unit"): (int, 2, MAX_WIDTH - 2),
    ("frac", "angle"): (int, 2, MAX_WIDTH - 3),
    ("cordic", "iterations"): (int, 4, 40),
    ("cordic", "guard_bits"): (int, 0, 8),
    ("cordic", "angle_guard_bits"): (int, 1, 8),
    ("ik", "singular_sin_q3"): (float, 0.0, 0.5),
    ("ik", "internal_guard_bits"): (int, 0, 8),
    ("ik", "reach_tolerance"): (float, 0.0, 0.5),
    ("ik", "orientation_tolerance"): (float, 1e-6, 0.5),
}
#: Optional fields and their defaults (a config without them behaves as before they existed).
_OPTIONAL = {("ik", "internal_guard_bits"): 0, ("ik", "reach_tolerance"): None,
             ("ik", "orientation_tolerance"): 1e-3}


#: Every key a config TOML may hold (tables and their keys); others are rejected.
_KEYS = {"name": None, "width": None, "frac": {"length", "unit", "angle"},
         "cordic": {"iterations", "guard_bits", "angle_guard_bits"},
         "ik": {"rounding", "singular_sin_q3", "internal_guard_bits", "reach_tolerance",
                "orientation_tolerance"}}


def _check_keys(doc: dict, path) -> None:
    """InputError naming the first unknown key (a misspelt one would otherwise be ignored)."""
    for key, value in doc.items():
        if key not in _KEYS:
            raise InputError(path, f"unknown key (known: {', '.join(_KEYS)})", field=key)
        known = _KEYS[key]
        if known is None:
            continue
        if not isinstance(value, dict):
            raise InputError(path, "must be a table", field=key)
        for sub in value:
            if sub not in known:
                raise InputError(path, f"unknown key (known in [{key}]: {', '.join(sorted(known))})",
                                 field=f"{key}.{sub}")


def parse_config(doc: dict, path: str | Path = "<config>") -> FixedConfig:
    """Validate a parsed config TOML; errors name ``path`` and the field."""
    _check_keys(doc, path)
    values = {}
    for keys, (kind, lo, hi) in _SCHEMA.items():
        name = ".".join(keys)
        node = doc
        for key in keys:
            if not isinstance(node, dict) or key not in node:
                if keys in _OPTIONAL:
                    node = _OPTIONAL[keys]
                    break
                raise InputError(path, "missing", field=name)
            node = node[key]
        if node is None:
            values[name] = None
            continue
        if isinstance(node, bool) or not isinstance(node, (int, float)) or (kind is int and not isinstance(node, int)):
            raise InputError(path, f"must be {'an integer' if kind is int else 'a number'}, got {node!r}", field=name)
        if not lo <= node <= hi:
            raise InputError(path, f"must be in [{lo}, {hi}], got {node}", field=name)
        values[name] = node
    width = values["width"]
    for name, spare in (("frac.length", 2), ("frac.unit", 2), ("frac.angle", 3)):
        if values[name] > width - spare:
            raise InputError(path, f"must leave {spare} integer bits in a {width}-bit word", field=name)
    rounding = doc.get("ik", {}).get("rounding", "nearest")
    if rounding not in ("nearest", "truncate"):
        raise InputError(path, f"must be 'nearest' or 'truncate', got {rounding!r}", field="ik.rounding")
    return FixedConfig(
        name=str(doc.get("name", Path(str(path)).stem)), width=width,
        frac_length=values["frac.length"], frac_unit=values["frac.unit"], frac_angle=values["frac.angle"],
        iterations=values["cordic.iterations"], guard_bits=values["cordic.guard_bits"],
        angle_guard_bits=values["cordic.angle_guard_bits"], rounding=rounding,
        singular_sin_q3=float(values["ik.singular_sin_q3"]),
        internal_guard_bits=values["ik.internal_guard_bits"], source=str(path),
        reach_tolerance=None if values["ik.reach_tolerance"] is None else float(values["ik.reach_tolerance"]),
        orientation_tolerance=float(values["ik.orientation_tolerance"]),
    )


def config_dir() -> Path:
    """The shipped configs: package data ``ik5r.configs`` (``configs/`` of the source tree)."""
    import importlib

    try:   # a data-only (namespace) package: its folder is its __path__
        return Path(next(iter(importlib.import_module("ik5r.configs").__path__)))
    except (ModuleNotFoundError, StopIteration):   # an install older than the package data
        return Path(str(resources.files("ik5r"))).resolve().parents[1] / "configs"


def shipped_configs() -> list[str]:
    return sorted(p.stem for p in config_dir().glob("*.toml"))


def resolve_config_path(path: str | Path | None) -> Path:
    """NAME (``q18``) is a shipped config wherever ik5r runs; PATH a file. A relative
    ``configs/NAME.toml`` that does not exist from here is the shipped one too, so the README's
    commands work from any directory."""
    candidate = Path(DEFAULT_CONFIG if path is None else path)
    if candidate.is_file():
        return candidate
    if not candidate.suffix and len(candidate.parts) == 1:
        shipped = config_dir() / f"{candidate.name}.toml"
        if shipped.is_file():
            return shipped
    elif not candidate.is_absolute() and candidate.parent == Path("configs"):
        shipped = config_dir() / candidate.name
        if shipped.is_file():
            return shipped
    raise InputError(path, f"no such config file or shipped config name "
                           f"(shipped: {', '.join(shipped_configs())})")


def load_config(path: str | Path | None = None) -> FixedConfig:
    """Load a config TOML; ``None`` gives :data:`DEFAULT_CONFIG`; a bare name ``q18`` a shipped one."""
    candidate = resolve_config_path(path)
    return parse_config(read_toml(candidate), candidate)


@dataclass(frozen=True)
class ConstMul:
    """Multiplication by a real constant c: ``y = rshift(rshift(x, pre) * mant, post)``.

    ``pre`` brings the largest |x| under 2**31 so the product fits int64; ``mant`` < 2**31.
    """

    pre: int
    mant: int
    post: int


def const_mul(factor: float, x_max_bits: int, mant_bits: int = CONST_MANT_BITS) -> ConstMul:
    """c = factor for operands below 2**x_max_bits: the pre-shifted operand and the mantissa are
    both below 2**mant_bits (31 for the word configs, so the product fits int64)."""
    pre = max(0, x_max_bits - mant_bits)
    scaled = abs(factor) * 2.0**pre
    post = mant_bits - 1 - math.floor(math.log2(scaled))
    mant = round(scaled * 2.0**post)
    if mant >= 2**mant_bits:
        post -= 1
        mant = round(scaled * 2.0**post)
    return ConstMul(pre, int(math.copysign(mant, factor)), post)


def _q(value: float, frac: int) -> int:
    return round(value * 2**frac)


class WideInt(int):
    """An integer constant that is a product of two words (a squared length), so wider than 64
    bits in the internal format: the C header carries it as two 64-bit halves of a 128-bit value."""


@dataclass(frozen=True)
class Constants:
    """Every integer constant of the fixed-point IK, derived from a config and an arm."""

    cfg: FixedConfig
    arm: Arm
    atan_table: tuple[int, ...] = field(init=False)   # atan(2^-i), Q(frac_angle + angle_guard_bits)
    inv_gain: int = field(init=False)                 # 1/K_N, Q(inv_gain_frac)

    def __post_init__(self):
        c, a = self.cfg, self.arm
        check_fits(c, a)      # an arm too big for the length format is refused, never saturated
        set_ = object.__setattr__
        zf = c.frac_angle + c.angle_guard_bits
        set_(self, "atan_table", tuple(_q(math.atan(2.0**-i), zf) for i in range(c.iterations)))
        gain = math.prod(math.sqrt(1 + 2.0 ** (-2 * i)) for i in range(c.iterations))
        # 1/K and the constant multipliers carry at least a word's precision: 31 bits for every
        # word config (products fit int64), width - 1 for the wider internal format.
        set_(self, "inv_gain_frac", max(INV_GAIN_FRAC, c.width - 1))
        set_(self, "const_mant_bits", max(CONST_MANT_BITS, c.width - 1))
        set_(self, "inv_gain", _q(1 / gain, self.inv_gain_frac))
        fl, fu, fa, w = c.frac_length, c.frac_unit, c.frac_angle, c.width
        set_(self, "z_frac", zf)
        set_(self, "half_pi_z", _q(math.pi / 2, zf))
        set_(self, "pi_a", _q(math.pi, fa))
        set_(self, "one_u", 1 << fu)
        set_(self, "word_max", (1 << (w - 1)) - 1)
        set_(self, "word_min", -(1 << (w - 1)))
        set_(self, "a1_l", _q(a.a[0], fl))
        set_(self, "a2_l", _q(a.a[1], fl))
        set_(self, "a4_l", _q(a.a[3], fl))
        set_(self, "d1_l", _q(a.d[0], fl))
        set_(self, "d5_l", _q(a.d[4], fl))
        set_(self, "offset_a", tuple(_q(o, fa) for o in a.theta_offset))
        set_(self, "sense", tuple(a.sense))
        lo_a, hi_a = _limit_words(a, fa, self.word_min, self.word_max)
        set_(self, "limit_lo_a", lo_a)
        set_(self, "limit_hi_a", hi_a)
        # Law of cosines in Q(2*frac_length): c3 = (D^2 - a2^2 - a3^2) / (2 a2 a3).
        set_(self, "links_sq_l2", WideInt(_q(a.a[1] ** 2 + a.a[2] ** 2, 2 * fl)))
        set_(self, "twice_a2a3_l2", WideInt(_q(2 * a.a[1] * a.a[2], 2 * fl)))
        mant_bits = self.const_mant_bits
        c3_factor = 2.0 ** (fu - 2 * fl) / (2 * a.a[1] * a.a[2])
        set_(self, "c3_from_l2", const_mul(c3_factor, self.twice_a2a3_l2.bit_length(), mant_bits))
        # 1 -+ c3 = (2 a2 a3 -+ num) / (2 a2 a3), operands in [0, 4 a2 a3]: the same factor, its
        # rounding relative to the (small, near the straight or folded elbow) complement.
        set_(self, "c3_complement_from_l2",
             const_mul(c3_factor, (2 * self.twice_a2a3_l2).bit_length(), mant_bits))
        set_(self, "a3_from_u", const_mul(a.a[2] * 2.0 ** (fl - fu), fu + 1, mant_bits))
        set_(self, "singular_s3_u", _q(c.singular_sin_q3, fu))
        # Reach: num = xw^2 + yw^2 - a2^2 - a3^2 beyond +-(2 a2 a3)(1 + reach tolerance) is
        # unreachable; between that and +-2 a2 a3 it is clipped (straight or folded elbow).
        set_(self, "reach_limit_l2", WideInt(_q(2 * a.a[1] * a.a[2] * (1 + c.reach_tol), 2 * fl)))
        # Orientation checks on check words: the top CHECK_BITS bits of a unit word (floor), so
        # that each product is one 17 x 17 signed product (one DSP, also as a MULT18X18D); products
        # in Q(2 check_frac).
        set_(self, "check_shift", max(0, w - CHECK_BITS))
        set_(self, "check_frac", fu - self.check_shift)
        set_(self, "check_one_c2", 1 << (2 * self.check_frac))
        set_(self, "check_tol_c2", _q(c.orientation_tolerance, 2 * self.check_frac))
        for name in ("a1_l", "a2_l", "a4_l", "d1_l", "d5_l", "pi_a", "one_u"):
            if not self.word_min <= getattr(self, name) <= self.word_max:
                raise InputError(c.source, f"{name} = {getattr(self, name)} does not fit {w} bits")
        # The constants of the format the IK runs on (cfg.internal()); these very ones when the
        # config has no internal guard bits.
        set_(self, "internal", self if c.internal_guard_bits == 0 else Constants(c.internal(), a))


    @property
    def limited(self) -> bool:
        """Some joint's limits leave out part of the turn: the status word has OUT_OF_LIMITS."""
        return any(lo != self.word_min for lo in self.limit_lo_a) or any(hi != self.word_max for hi in self.limit_hi_a)

    @property
    def status_width(self) -> int:
        """Bits of the solvers' status word: 6, or 7 with OUT_OF_LIMITS (an arm with limits)."""
        return (st.FIXED_BITS | (st.OUT_OF_LIMITS if self.limited else 0)).bit_length()


def _limit_words(arm: Arm, frac_angle: int, word_min: int, word_max: int) -> tuple[tuple, tuple]:
    """Per joint, the smallest and the largest output word within the arm's limits; word_min
    (word_max) where the limit is at or beyond -pi (pi): that side is not checked, so an arm whose
    limits are all full turns has no limit check in any layer. A word q is within [lo, hi] exactly
    when ceil(lo 2^fa) <= q <= floor(hi 2^fa) (the joint the solver reports is q 2^-fa, exact)."""
    lows, highs = [], []
    for j, (lo, hi) in enumerate(arm.limits):
        if lo <= -math.pi and hi >= math.pi:
            lows.append(word_min)
            highs.append(word_max)
            continue
        if lo < -math.pi or hi > math.pi:
            raise InputError(arm.source, f"arm {arm.name}: the limits of joint {j + 1} cross +-180 deg "
                             "without covering the turn; the fixed-point solvers check limits within "
                             "[-180, 180] deg (their joints' range)", field=f"joint[{j + 1}].limits")
        lows.append(word_min if lo <= -math.pi else math.ceil(lo * 2.0 ** frac_angle))
        highs.append(word_max if hi >= math.pi else math.floor(hi * 2.0 ** frac_angle))
    return tuple(lows), tuple(highs)


def constants(cfg: FixedConfig | None = None, arm: Arm | None = None) -> Constants:
    return Constants(cfg or load_config(), arm or load_arm())


def quantize(values, frac: int, cfg: FixedConfig):
    """Real values to words with ``frac`` fraction bits, rounded to nearest and saturated.

    Returns (raw int64 array, saturated bool array). Non-finite values give 0 and saturated=False;
    the caller flags them as invalid input.
    """
    import numpy as np

    values = np.asarray(values, dtype=np.float64)
    finite = np.isfinite(values)
    scaled = np.where(finite, values, 0.0) * 2.0**frac
    lo, hi = -(2 ** (cfg.width - 1)), 2 ** (cfg.width - 1) - 1
    saturated = finite & ((scaled < lo) | (scaled > hi))
    return np.clip(np.round(scaled), lo, hi).astype(np.int64), saturated
