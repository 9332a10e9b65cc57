"""Arc cosine: :class:`Acos`, bit-exact to ``model.cordic_acos``."""

from __future__ import annotations

from amaranth.hdl import Mux, signed, unsigned

from ik5r.core.fxconfig import Constants
from ik5r.core.modes import Block, Dsp

from .cordic import add_atan2
from ..datapath.adders import adders_for
from ..datapath.stages import Datapath
from ..datapath.expr import drop
from ..datapath.products import add_products
from .sqrt import add_isqrt, fit
from .stream_block import StreamBlock, micro_steps

__all__ = ["Acos"]


class Acos(StreamBlock):
    """``acos(x)`` of a unit-format word as ``atan2(sqrt((1 - x)(1 + x)), x)``, bit-exact to
    ``model.cordic_acos``; the sine comes out too.

    Stages: clip x to [-1, 1] (flagging it), form 1 - x and 1 + x, multiply them (partial
    products and an adder tree; the product has 2 * frac_unit fraction bits and is below
    2**(2 * frac_unit + 1)), take its square root by digit recurrence over 2 * frac_unit + 2 bits
    (the :class:`~ik5r.hdl.blocks.sqrt.Sqrt` datapath) to get the sine, then run the
    :class:`~ik5r.hdl.blocks.cordic.Atan2` vectoring datapath (without magnitude) on (sine, x).

    Payloads (W = ``constants.cfg.width``, fu = ``frac_unit``, fa = ``frac_angle``):

    * ``i.payload.x``: ``signed(W)``, Q(W - fu).fu (unit format); outside [-1, 1] it is clipped.
    * ``o.payload.angle``: ``signed(W)``, Q(W - fa).fa radians in [0, pi].
    * ``o.payload.sine``: ``signed(W)``, Q(W - fu).fu, sqrt(1 - x^2) in [0, 1] (>= 0).
    * ``o.payload.saturated``: 1 bit, set iff x was clipped.
    * ``tag`` (only if ``tag_width``): ``unsigned(tag_width)``, carried unchanged.

    Timing: ``latency`` = 2 + multiplier stages (4 up to 34-bit factors) + (fu + 1) digits + 2
    (rounding to nearest; 0 when truncating) + 4 + iterations + 1 stages, plus 3 for the output FIFO
    of the pipelined architecture and the register in front of it. Throughput: ``"pipelined"`` one result per cycle, never stalling: results
    queue in the output FIFO while ``o`` is held, and ``i.ready`` drops only when ``capacity`` items
    are inside (see :class:`~ik5r.hdl.blocks.stream_block.StreamBlock`); ``"iterative"``
    one square-root digit or micro-rotation per cycle, one result every ``latency`` cycles.

    Parameters
    ----------
    constants : Constants
    arch : ``"pipelined"`` or ``"iterative"``
    dsp : ``"generic"`` or ``"ecp5"``
        Multipliers of the pipelined arch (see :data:`~ik5r.core.modes.DSPS`).
    tag_width : int
        Width of the optional ``tag`` field (0: none).
    """

    def __init__(self, *, constants: Constants, arch: str, tag_width: int = 0, dsp: str = Dsp.GENERIC,
                 rotations_per_stage: int = 1):
        dp = in_fields = out_fields = None
        if isinstance(constants, Constants):
            k, c = constants, constants.cfg
            dp = self.chain(k, adders=adders_for(dsp), steps_per_stage=micro_steps(arch, rotations_per_stage))
            word = signed(c.width)
            in_fields = {"x": (word, c.frac_unit, "cosine, unit format")}
            out_fields = {"angle": (word, c.frac_angle, "acos(x), radians, in [0, pi]"),
                          "sine": (word, c.frac_unit, "sqrt((1 - x)(1 + x)), unit format"),
                          "saturated": (unsigned(1), 0, "x was outside [-1, 1] and clipped")}
        super().__init__(constants=constants, arch=arch, tag_width=tag_width, in_fields=in_fields,
                         out_fields=out_fields, datapath=dp, dsp=dsp, rotations_per_stage=rotations_per_stage)

    @staticmethod
    def chain(k: Constants, radicand_bits: int | None = None, *,
              adders=None, steps_per_stage: int | None = None) -> Datapath:
        """The arc cosine as a chain: input ``x``; outputs ``angle``, ``sine``, ``saturated``.
        Split points (the IK core composes the parts): ``"factors"`` in front of 1 -+ x (reads
        the clipped ``ac_x``), ``"radicand"`` in front of their product (reads ``ac_a``,
        ``ac_b``, ``ac_x``), ``"atan2"`` in front of the vectoring (reads ``at_y``, ``ac_x``).
        ``radicand_bits``: the square root's (default 2 frac_unit + 2: (1 - x)(1 + x) <= 1;
        the IK core's internal format takes factors up to 2 each, so 2 frac_unit + 4).
        ``adders``: the add/subtract mapping (generic when None); ``steps_per_stage``: square-root
        digits and micro-rotations per pipeline stage (None: the context's, see
        :func:`~ik5r.hdl.datapath.stages.steps_per_stage`)."""
        c = k.cfg
        width, fu, one = c.width, c.frac_unit, k.one_u
        dp = Datapath(Block.ACOS, adders=adders, inputs=("x",),
                      outputs=("angle", "sine", "saturated"), steps_per_stage=steps_per_stage)
        dp.declare(ac_x=signed(width))

        def clip(s):
            x = s["x"]
            over, under = x > one, x < -one
            out = drop(s, "x")
            out["ac_x"] = Mux(over, one, Mux(under, -one, x))
            out["saturated"] = over | under
            return out

        def factors(s):
            # 1 - x and 1 + x, both in [0, 2**(fu + 1)]: unsigned(fu + 2).
            return dict(s, ac_a=(one - s["ac_x"])[:fu + 2], ac_b=(one + s["ac_x"])[:fu + 2])

        dp.add("ac_clip", clip)
        dp.mark("factors")
        dp.add("ac_factors", factors)
        dp.mark("radicand")
        factor = unsigned(fu + 2)
        add_products(dp, "ac_sq", [(lambda s: s["ac_a"], factor,
                                    (lambda s: s["ac_b"], factor), "sq_rad")],
                     drop_keys=("ac_a", "ac_b"))
        add_isqrt(dp, bits=radicand_bits or 2 * fu + 2, nearest=c.round_nearest, root="sine")
        # sine <= 2**fu < 2**(W-1): the same value as a signed word (wiring only).
        dp.add_wiring(lambda s: dict(s, sine=fit(s["sine"], width).as_signed(),
                                     at_y=fit(s["sine"], width).as_signed()))
        dp.mark("atan2")
        add_atan2(dp, k, y="at_y", x="ac_x", magnitude=False, zero=False)
        return dp

    def _inputs(self, payload):
        return {"x": payload.x}

    def _outputs(self, state):
        return {"angle": state["angle"], "sine": state["sine"], "saturated": state["saturated"]}
