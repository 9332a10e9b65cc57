"""Per-pose status bits, shared by the float reference, the C solver, its models and the HDL.

Tolerances (``ik.reach_tolerance``, ``ik.orientation_tolerance`` of the config; the float
reference's defaults :data:`ik5r.core.reference.REACH_TOLERANCE`, :data:`ORIENTATION_TOLERANCE`):

* elbow cosine c3 beyond +-1 by at most ``reach_tolerance``: the elbow is straight or folded
  (``singular_elbow``), the pose is reachable; beyond it: ``unreachable``.
* ``bad_orientation``: the approach leaves the arm's plane (sine of its angle to the plane above
  ``orientation_tolerance``), or n, o, a are not a right-handed orthonormal frame (|n.n - 1|,
  |o.o - 1|, |n.o| or a component of n x o - a above ``orientation_tolerance``; only when n, o
  are given). The joints are those of the projected approach.
"""

OK = 0
UNREACHABLE = 1 << 0      # c3 beyond +-(1 + reach tolerance): q3 clipped to straight or folded
SINGULAR_ELBOW = 1 << 1   # |sin q3| <= singular_sin_q3 (elbow straight or folded)
SINGULAR_BASE = 1 << 2    # tool point on the base axis and approach vertical: q1 free
SATURATED = 1 << 3        # a fixed-point value was clipped to the word range
INVALID = 1 << 4          # non-finite or out-of-range input, or approach (n/o) with no component in the arm's plane
BAD_ORIENTATION = 1 << 5  # approach off the arm's plane, or n, o, a not a right-handed orthonormal frame
OUT_OF_LIMITS = 1 << 6    # the branch violates a joint limit (fixed point: only arms with limits)

#: Bits the fixed-point solvers (model, C, HDL) produce for an arm whose limits are all full
#: turns: the hardware's status word. An arm with limits adds OUT_OF_LIMITS (7 bits,
#: ``Constants.status_width``); the rule is in docs/algorithm.md, "Joint limits".
FIXED_BITS = UNREACHABLE | SINGULAR_ELBOW | SINGULAR_BASE | SATURATED | INVALID | BAD_ORIENTATION
#: Width of that status word (without OUT_OF_LIMITS).
FIXED_WIDTH = FIXED_BITS.bit_length()

NAMES = {
    UNREACHABLE: "unreachable",
    SINGULAR_ELBOW: "singular_elbow",
    SINGULAR_BASE: "singular_base",
    SATURATED: "saturated",
    INVALID: "invalid",
    BAD_ORIENTATION: "bad_orientation",
    OUT_OF_LIMITS: "out_of_limits",
}


def describe(bits: int) -> str:
    """'ok', or the names of the set bits joined by '+'."""
    bits = int(bits)
    return "+".join(name for bit, name in NAMES.items() if bits & bit) or "ok"


def describe_all(bits) -> list[str]:
    """:func:`describe` of every element of an integer array (each distinct value once)."""
    import numpy as np

    values, inverse = np.unique(np.asarray(bits, dtype=np.int64), return_inverse=True)
    names = np.array([describe(v) for v in values.tolist()], dtype=object)
    return names[inverse.reshape(-1)].tolist()


def status_class(bits: int) -> str:
    """What happened, comparable between the float and the fixed-point layers: ``invalid`` when
    that bit is set (whatever else), else :func:`describe` without ``saturated`` (a fixed-point
    range only)."""
    bits = int(bits)
    if bits & INVALID:
        return "invalid"
    return describe(bits & ~SATURATED)
