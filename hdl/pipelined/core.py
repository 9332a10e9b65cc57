"""The inverse kinematics of the 5R arm in hardware: :class:`IKCore`, bit-exact to ``model.ik_solve``.

The whole solver is ONE :class:`~ik5r.hdl.datapath.stages.Datapath`
(:func:`~ik5r.hdl.pipelined.graph.graph_datapath`) generated from the dataflow graph of the IK's one
description, :func:`ik5r.core.ik.solve`, traced on symbols (:func:`~ik5r.hdl.graph.trace.trace`,
the graph the compact core's program is compiled from): a unit per value of the graph
(:mod:`~ik5r.hdl.pipelined.units`: the blocks' chains, :func:`~ik5r.hdl.blocks.cordic.add_atan2`,
:meth:`~ik5r.hdl.blocks.cordic.Rotate.chain`, :func:`~ik5r.hdl.blocks.sqrt.add_isqrt`,
:func:`~ik5r.hdl.datapath.products.add_products`, and glue stages), scheduled as soon as their operands are
ready; values needed many stages later wait in the stash (:mod:`~ik5r.hdl.datapath.stash`).
"""

from __future__ import annotations

from ik5r.core.fxconfig import Constants
from ik5r.core.modes import Arch, CoreArch, Dsp

from ..datapath.adders import adders_for
from ..datapath.stages import steps_per_stage
from ..graph.inputs import core_fields
from .graph import graph_datapath
from ..blocks.stream_block import StreamBlock, micro_steps

__all__ = ["IKCore"]


class IKCore(StreamBlock):
    """The fixed-point inverse kinematics of the 5R arm, bit-exact to ``model.ik_solve``.

    One pose in, one branch's joint angles and status out. The branch is chosen per pose, as in
    the C solver's API (``ik5r_solve(..., has_roll, shoulder_back, elbow_down, q5_default_a, q)``):
    ``shoulder_back`` puts the tool point behind joint 1 (q1 + pi, r = -rho), ``elbow_down`` takes
    q3 = -acos(c3) (q2 = gamma + beta) instead of +acos(c3) (q2 = gamma - beta). Without roll
    (``has_roll`` low) n and o are ignored and q5 = ``q5_default`` (wrapped).

    Dataflow (docs/algorithm.md; every step is the model's, in the model's integer arithmetic):
    select (point, or approach on the base axis) -> [atan2 theta1 || px^2 + py^2, isqrt, sat rho]
    -> q1, r - a1 -> rotate (1, 0) by q1 -> six products: a_radial, s5, c5 -> [atan2 pitch ||
    atan2 roll] -> phi -> rotate (a4, d5) by phi -> wrist centre (xw, yw) -> [atan2 gamma ||
    xw^2 + yw^2 - links, clip, c3 = mul_const, clip, (1 - c3)(1 + c3), isqrt = sin q3] ->
    [atan2(sin q3, c3) = acos || a3 sin q3, a2 + a3 c3, atan2 beta] -> q2, q3, q4 -> offsets, wrap.
    Parallel CORDICs share stages; values needed much later are stashed in delay lines.

    With ``ik.internal_guard_bits`` = G > 0 (q32w: G = 6) every step runs on the internal format
    (W + G-bit words, every fraction + G, iterations + G; 1 -+ c3 as two constant multiplies of
    the law of cosines' terms instead of c3 and 1 -+ c3); the input words are shifted up on entry and
    the joints rounded back to words (flagging ``saturated`` if one overflows).

    Payloads (W = ``constants.cfg.width``; Q m.n: n fraction bits, m + n = W):

    * ``i.payload``: ``px``, ``py``, ``pz`` ``signed(W)`` Q.frac_length cm; ``ax``, ``ay``, ``az``,
      ``nx``, ``ny``, ``nz``, ``ox``, ``oy``, ``oz`` ``signed(W)`` Q.frac_unit (nz, oz only in the
      orientation check); ``has_roll``, ``shoulder_back``, ``elbow_down`` 1 bit; ``q5_default``
      ``signed(W)`` Q.frac_angle rad; ``tag`` ``unsigned(tag_width)`` (only if ``tag_width``).
      Every word is accepted (full-scale and most negative inputs give the model's result).
    * ``o.payload``: ``q1`` .. ``q5`` ``signed(W)`` Q.frac_angle rad in [-pi, pi] (q5: the wrapped
      default without roll); ``status`` ``unsigned(6)``, the bits of :mod:`ik5r.core.status`
      (unreachable, singular_elbow, singular_base, saturated, invalid, bad_orientation); ``tag``,
      the input's.

    Timing: ``latency`` cycles from the input transfer to the output valid (no back-pressure;
    pipelined: the stages, the register in front of the output FIFO and the FIFO; the figures of
    each config are in the port map JSON and the records, not here).

    ``arch`` is ``"pipelined"``: one pose per clock (``cycles_per_result`` = 1), results in
    order. The pipeline never stalls (no clock enable): results queue in an output FIFO (block
    RAM) while ``o`` is held, and ``i.ready`` drops only when ``capacity`` poses are inside, in
    flight or queued (see :class:`~ik5r.hdl.blocks.stream_block.StreamBlock`). One add/sub level
    (or one 17 x 17 partial product) per stage; a compare that selects a value is registered a
    stage ahead of its select. ``dsp="ecp5"`` builds the partial products as ``MULT18X18D``
    instances with their input and output registers and the CORDIC add/subtracts as ``CCU2C``
    chains (same latency, same bits). ``rotations_per_stage`` (1, 2 or 4): CORDIC
    micro-rotations and square-root digits per pipeline stage, the same steps in fewer, longer
    stages (fewer cycles of latency, a lower Fmax; same bits). ``dsp_output_regs`` (0, 1 or 2;
    ``dsp="ecp5"``): fabric registers after each DSP's output register, so a DSP's output has a
    clock to reach the fabric (a cycle of latency more per product stage on the way; same
    bits). The small IK core (``compact``) is another design, the sequenced engine
    :class:`~ik5r.hdl.sequenced.engine.SequencedIKCore`.
    """

    def __init__(self, *, constants: Constants, arch: str, tag_width: int = 0,
                 dsp: str = Dsp.GENERIC, rotations_per_stage: int = 1, max_dsp: int | None = None,
                 dsp_output_regs: int = 0):
        if arch != CoreArch.PIPELINED:
            raise ValueError(f"IKCore is the {CoreArch.PIPELINED} IK core, got arch {arch!r} (the "
                             f"{CoreArch.COMPACT} one is hdl.sequenced.engine.SequencedIKCore)")
        dp = in_fields = out_fields = None
        if isinstance(constants, Constants):
            in_fields, out_fields = core_fields(constants)
            # The blocks' chains the graph's units are made of take the micro-rotations (and
            # square-root digits) per stage from the context.
            with steps_per_stage(micro_steps(Arch.PIPELINED, rotations_per_stage)):
                dp = graph_datapath(constants, bool(tag_width), adders_for(dsp, dsp_output_regs))
        self.options = {}
        super().__init__(constants=constants, arch=Arch.PIPELINED, tag_width=tag_width, in_fields=in_fields,
                         out_fields=out_fields, datapath=dp, dsp=dsp, rotations_per_stage=rotations_per_stage,
                         max_dsp=max_dsp, dsp_output_regs=dsp_output_regs)
        self.arch = arch

    def _inputs(self, p):
        # Words to the internal format: exact, ``internal_guard_bits`` more fraction bits.
        guard = self.constants.cfg.internal_guard_bits
        def word(value):
            return value.shift_left(guard)

        return {"px": word(p.px), "py": word(p.py), "pz": word(p.pz), "ax": word(p.ax),
                "ay": word(p.ay), "az": word(p.az), "nx": word(p.nx), "ny": word(p.ny),
                "nz": word(p.nz), "ox": word(p.ox), "oy": word(p.oy), "oz": word(p.oz), "roll": p.has_roll, "q5d": word(p.q5_default),
                "back": p.shoulder_back, "down": p.elbow_down}

    def _outputs(self, state):
        out = {f"q{j}": state[f"j{j}"] for j in range(1, 6)}
        out["status"] = state["st"]
        return out
