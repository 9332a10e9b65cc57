"""Per-pose status bits, shared by the float reference, the C solver, its models and the HDL."""

OK = 0
UNREACHABLE = 1 << 0      # |D| outside [|a2 - a3|, a2 + a3]: q3 clipped to straight or folded
SINGULAR_ELBOW = 1 << 1   # |sin q3| <= singular_sin_q3 (elbow straight or folded)
SINGULAR_BASE = 1 << 2    # tool point on the base axis and approach vertical: q1 free
SATURATED = 1 << 3        # a fixed-point value was clipped to the word range
INVALID = 1 << 4          # non-finite input, or approach (n/o) with no component in the arm's plane
OUT_OF_LIMITS = 1 << 5    # float reference only: the branch violates a joint limit

NAMES = {
    UNREACHABLE: "unreachable",
    SINGULAR_ELBOW: "singular_elbow",
    SINGULAR_BASE: "singular_base",
    SATURATED: "saturated",
    INVALID: "invalid",
    OUT_OF_LIMITS: "out_of_limits",
}


def describe(bits: int) -> str:
    """'ok', or the names of the set bits joined by '+'."""
    bits = int(bits)
    return "+".join(name for bit, name in NAMES.items() if bits & bit) or "ok"
