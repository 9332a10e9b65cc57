"""Square root by digit recurrence: :class:`Sqrt`, bit-exact to ``model.sqrt_word`` / ``model.isqrt``."""

from __future__ import annotations

from amaranth.hdl import Cat, Const, Mux, Value, signed, unsigned

from ik5r.core.fxconfig import Constants
from ik5r.core.modes import Block, Dsp

from ..datapath.adders import adders_for
from ..datapath.stages import Datapath
from ..datapath.expr import drop
from .stream_block import StreamBlock, micro_steps

__all__ = ["Sqrt", "add_isqrt", "isqrt_root_bits", "fit"]


def fit(value, bits: int):
    """``value`` as exactly ``bits`` bits: truncated, or extended by its sign (or zeros)."""
    value = Value.cast(value)
    if len(value) >= bits:
        return value[:bits]
    fill = value[-1] if value.shape().signed else Const(0, 1)
    return Cat(value, fill.replicate(bits - len(value)))


def isqrt_root_bits(bits: int, nearest: bool) -> int:
    """Width of ``model.isqrt(r, bits, nearest)`` for any r < 2**bits (the rounding may carry)."""
    return bits // 2 + (1 if nearest else 0)


def add_isqrt(dp: Datapath, *, bits: int, nearest: bool, root: str):
    """Append ``model.isqrt(state["sq_rad"], bits, nearest)`` to ``dp``: ``bits // 2`` digit
    stages (one radicand bit pair each: one subtraction) and, when rounding to nearest, a
    comparison stage and an increment stage. The radicand ``sq_rad`` must be given as ``bits``
    bits (see :func:`fit`; the model reads only those). Produces ``root``.

    Bounds: after j digits root < 2**j and 0 <= rem <= 2 * root, so rem fits n + 1 bits
    (n = bits // 2) and the trial ``(rem << 2 | pair) - (root << 2 | 1)`` fits signed(n + 5).
    """
    if bits < 2 or bits % 2:
        raise ValueError(f"radicand bits must be even and >= 2, got {bits}")
    digits = bits // 2
    dp.declare(sq_rad=unsigned(bits), sq_rem=unsigned(digits + 2), sq_root=unsigned(digits + 1))

    def digit(s, i):
        # On entry rem = root = 0 (not yet in the state: the iterative feedback mux gives 0).
        rad = s["sq_rad"]
        rem = s.get("sq_rem", Const(0, 1))
        acc = s.get("sq_root", Const(0, 1))
        pair = rad[bits - 2:bits]
        rem2 = Cat(pair, rem)                       # (rem << 2) | pair
        trial = Cat(Const(1, 2), acc)               # (root << 2) | 1
        diff = rem2 - trial
        take = ~diff[-1]                            # rem2 >= trial
        out = dict(s)
        out["sq_rad"] = rad.shift_left(2)[:bits]
        out["sq_rem"] = Mux(take, diff, rem2)
        out["sq_root"] = Cat(take, acc)
        return out

    dp.add_micro_steps("sq_digit", digit, digits)
    if nearest:
        def compare(s):
            out = drop(s, "sq_rad", "sq_rem", "sq_root")
            out["sq_up"] = s["sq_rem"] > s["sq_root"]
            out["sq_acc"] = s["sq_root"]
            return out

        def increment(s):
            out = drop(s, "sq_up", "sq_acc")
            out[root] = s["sq_acc"] + s["sq_up"]
            return out

        dp.add("sq_cmp", compare)
        dp.add("sq_inc", increment)
    else:
        def rename(s):
            out = drop(s, "sq_rad", "sq_rem", "sq_root")
            out[root] = s["sq_root"][:digits]
            return out

        dp.add_wiring(rename)
    return digits + (2 if nearest else 0)


class Sqrt(StreamBlock):
    """Square root by the restoring digit recurrence, bit-exact to ``model.sqrt_word`` (word mode)
    or ``model.isqrt`` (radicand mode). One radicand bit pair (one result bit) per stage; a
    rounding to nearest adds a compare and an increment stage (``rem > root``: root + 1).

    Word mode (``frac``; default ``constants.cfg.frac_length``): ``sqrt_word(x, frac)``, i.e.
    ``isqrt(x << frac, bits)`` with ``bits = W + frac`` rounded up to even.

    * ``i.payload.x``: ``signed(W)``, Q(W - frac).frac, x >= 0. (A negative x gives the model's
      result too: the square root of the radicand's two's-complement bits modulo 2**bits.)
    * ``o.payload.root``: ``unsigned(W)``, Q(W - frac).frac; below 2**(W-1) for x >= 0, so the
      same bits as a non-negative signed word.

    Radicand mode (``radicand_bits`` = R, even; e.g. 64 for the IK's sqrt(px^2 + py^2)):
    ``isqrt(x, R)``.

    * ``i.payload.x``: ``unsigned(R)``, an integer.
    * ``o.payload.root``: ``unsigned(R/2 + 1)`` when rounding to nearest (the rounding can carry
      to 2**(R/2)), else ``unsigned(R/2)``.

    Both: ``tag`` (only if ``tag_width``) ``unsigned(tag_width)``, carried unchanged.

    Timing: ``latency`` = bits/2 stages (+ 2 when rounding to nearest), plus 3 for the output FIFO
    of the pipelined architecture and the register in front of it.
    Throughput: ``"pipelined"`` one result per cycle, never stalling: results queue in the output
    FIFO while ``o`` is held, and ``i.ready`` drops only when ``capacity`` items are inside (see
    :class:`~ik5r.hdl.blocks.stream_block.StreamBlock`); ``"iterative"`` one digit per cycle, one result every
    ``latency`` cycles.

    Parameters
    ----------
    constants : Constants
    arch : ``"pipelined"`` or ``"iterative"``
    tag_width : int
        Width of the optional ``tag`` field (0: none).
    frac : int
        Fraction bits of the word (0 <= frac <= W - 2); not with ``radicand_bits``.
    radicand_bits : int
        Width of an unsigned integer radicand (even, 2..128); not with ``frac``.
    """

    def __init__(self, *, constants: Constants, arch: str, tag_width: int = 0,
                 frac: int | None = None, radicand_bits: int | None = None, dsp: str = Dsp.GENERIC,
                 rotations_per_stage: int = 1):
        dp = in_fields = out_fields = None
        if frac is not None and radicand_bits is not None:
            raise ValueError("give frac or radicand_bits, not both")
        if isinstance(constants, Constants):
            c = constants.cfg
            width = c.width
            dp = Datapath(Block.SQRT, adders=adders_for(dsp), steps_per_stage=micro_steps(arch, rotations_per_stage))
            if radicand_bits is None:
                if frac is None:
                    frac = c.frac_length
                if isinstance(frac, bool) or not isinstance(frac, int) or not 0 <= frac <= width - 2:
                    raise ValueError(f"frac must be an integer in [0, {width - 2}], got {frac!r}")
                bits = width + frac + ((width + frac) & 1)
                in_fields = {"x": (signed(width), frac, "radicand word, >= 0")}
                out_fields = {"root": (unsigned(width), frac, "sqrt(x), rounded per config")}
                self.options = {"frac": frac}
            else:
                if (isinstance(radicand_bits, bool) or not isinstance(radicand_bits, int)
                        or radicand_bits < 2 or radicand_bits % 2 or radicand_bits > 128):
                    raise ValueError(
                        f"radicand_bits must be an even integer in [2, 128], got {radicand_bits!r}")
                bits = radicand_bits
                in_fields = {"x": (unsigned(bits), 0, "unsigned integer radicand")}
                out_fields = {"root": (unsigned(isqrt_root_bits(bits, c.round_nearest)), 0,
                                       "isqrt(x), rounded per config")}
                self.options = {"radicand_bits": radicand_bits}
            self.bits = bits
            add_isqrt(dp, bits=bits, nearest=c.round_nearest, root="root")
        self.frac = frac
        self.radicand_bits = radicand_bits
        super().__init__(constants=constants, arch=arch, tag_width=tag_width, in_fields=in_fields,
                         out_fields=out_fields, datapath=dp, dsp=dsp, rotations_per_stage=rotations_per_stage)

    def _inputs(self, payload):
        if self.radicand_bits is not None:
            return {"sq_rad": payload.x}
        # x << frac, sign-extended to `bits` bits (the model reads x << frac modulo 2**bits).
        return {"sq_rad": fit(payload.x.shift_left(self.frac), self.bits)}

    def _outputs(self, state):
        return {"root": state["root"]}
