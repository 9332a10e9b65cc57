"""The stream block base class: ``i``/``o`` streams of ``lib.data`` struct payloads around a
:class:`~ik5r.hdl.datapath.stages.Datapath`, elaborated in the architecture asked for."""

from __future__ import annotations

from amaranth.hdl import Module, Signal, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from ik5r.core.fxconfig import Constants
from ik5r.core.modes import ARCHS, DSPS, Arch, Dsp

from ..datapath.build import build
from ..datapath.stages import check_steps_per_stage

__all__ = ["StreamBlock", "check_common", "micro_steps"]


def micro_steps(arch, rotations_per_stage) -> int:
    """A block's ``rotations_per_stage`` argument, validated for its ``arch`` (see
    :func:`~ik5r.hdl.datapath.stages.check_steps_per_stage`)."""
    return check_steps_per_stage(rotations_per_stage, arch if arch in ARCHS else Arch.PIPELINED)


def check_common(constants, arch, tag_width, dsp=Dsp.GENERIC):
    if not isinstance(constants, Constants):
        raise TypeError(f"constants must be an ik5r.core.fxconfig.Constants, got {constants!r}")
    if arch not in ARCHS:
        raise ValueError(f"arch must be one of {ARCHS}, got {arch!r}")
    if isinstance(tag_width, bool) or not isinstance(tag_width, int) or tag_width < 0:
        raise ValueError(f"tag_width must be a non-negative integer, got {tag_width!r}")
    if dsp not in DSPS:
        raise ValueError(f"dsp must be one of {DSPS}, got {dsp!r}")
    if dsp != Dsp.GENERIC and arch != Arch.PIPELINED:
        raise ValueError(f"dsp={dsp!r} applies to the pipelined architecture, not {arch!r}")


class StreamBlock(wiring.Component):
    """Base of the arithmetic blocks: ``i``/``o`` streams of struct payloads around a Datapath.

    Flow control. ``"pipelined"``: the pipeline never stalls; results queue in an output FIFO
    (block RAM) of ``capacity`` entries, read through ``o``. ``i.ready`` is low only while
    ``capacity`` items are inside (in flight or queued): when ``o`` is held, the block takes
    ``capacity`` more items, then waits; when ``o`` is taken every cycle it takes one item per
    clock, never lowering ``i.ready``. ``"iterative"``: one item inside (``capacity`` = 1).

    Subclasses pass ``datapath`` (made with ``adders=adders_for(dsp)``), ``in_fields`` /
    ``out_fields`` (dicts name -> ``(shape, frac, description)``; frac is the number of fraction
    bits or ``None`` when the field is format-agnostic) and implement ``_inputs(payload) ->
    state`` and ``_outputs(state) -> {field: value}``. The datapath is checked at construction
    (:meth:`~ik5r.hdl.datapath.stages.Datapath.check`) from the inputs to the output fields.
    """

    def __init__(self, *, constants, arch, tag_width, in_fields, out_fields, datapath,
                 dsp=Dsp.GENERIC, rotations_per_stage=1, max_dsp=None, dsp_output_regs=0):
        check_common(constants, arch, tag_width, dsp)
        if max_dsp is not None and (dsp != Dsp.ECP5 or not isinstance(max_dsp, int) or max_dsp < 0):
            raise ValueError(f"max_dsp (a non-negative int) applies to dsp={Dsp.ECP5.value!r}, "
                             f"got max_dsp={max_dsp!r} with dsp={dsp!r}")
        if (datapath.adders.dsp, datapath.adders.dsp_output_regs) != (dsp, dsp_output_regs):
            raise ValueError(f"datapath {datapath.name!r} made with adders for {datapath.adders.dsp!r} "
                             f"(dsp_output_regs={datapath.adders.dsp_output_regs}), block built with "
                             f"dsp={dsp!r} (dsp_output_regs={dsp_output_regs!r})")
        self.constants = constants
        self.arch = arch
        self.tag_width = tag_width
        #: Multiplier mapping of the pipelined architecture, one of :data:`DSPS`.
        self.dsp = dsp
        if dsp != Dsp.GENERIC:
            self.options = dict(getattr(self, "options", {}), dsp=dsp)
        #: CORDIC micro-rotations (and square-root digits) per pipeline stage.
        self.rotations_per_stage = micro_steps(arch, rotations_per_stage)
        if rotations_per_stage != 1:
            self.options = dict(getattr(self, "options", {}), rotations_per_stage=rotations_per_stage)
        #: Cap on the MULT18X18D count of ``dsp="ecp5"`` (None: no cap; the rest in LUTs).
        self.max_dsp = max_dsp
        if max_dsp is not None:
            self.options = dict(getattr(self, "options", {}), max_dsp=max_dsp)
        #: Fabric registers after each DSP output of ``dsp="ecp5"`` (0: the DSP's own register only).
        self.dsp_output_regs = dsp_output_regs
        if dsp_output_regs:
            self.options = dict(getattr(self, "options", {}), dsp_output_regs=dsp_output_regs)
        if tag_width:
            in_fields = dict(in_fields, tag=(unsigned(tag_width), 0, "carried unchanged to o.tag"))
            out_fields = dict(out_fields, tag=(unsigned(tag_width), 0, "i.tag of the same item"))
        self.in_fields = in_fields
        self.out_fields = out_fields
        self._dp = datapath
        #: The architecture the datapath is built in (a subclass may name its own differently).
        self._datapath_arch = arch
        #: Cycles from an input transfer (cycle c) to its result on the output (cycle c + latency)
        #: when the output is not held.
        self.latency = datapath.stream_latency(arch)
        #: Clock cycles per result at full rate (1 pipelined; latency iterative).
        self.cycles_per_result = 1 if arch == Arch.PIPELINED else datapath.latency
        #: Items the block holds at most: while ``o`` is held it accepts this many.
        self.capacity = datapath.capacity(arch)
        super().__init__({
            "i": In(stream.Signature(data.StructLayout(
                {name: shape for name, (shape, _, _) in in_fields.items()}))),
            "o": Out(stream.Signature(data.StructLayout(
                {name: shape for name, (shape, _, _) in out_fields.items()}))),
        })
        datapath.check(self._state_of(Signal(self.i.payload.shape(), name="check_payload")),
                       self._payload)

    def _inputs(self, payload) -> dict:
        raise NotImplementedError

    def _outputs(self, state) -> dict:
        raise NotImplementedError

    def _state_of(self, payload) -> dict:
        """The datapath's input state of a payload (tag included)."""
        state = self._inputs(payload)
        if self.tag_width:
            state["tag"] = payload.tag
        return state

    def _payload(self, final) -> dict:
        """The output payload fields of the datapath's final state (tag included)."""
        outputs = self._outputs(final)
        if self.tag_width:
            outputs["tag"] = final["tag"]
        return outputs

    def elaborate(self, platform):
        m = Module()
        state = self._state_of(self.i.payload)
        build(self._dp, m, self._datapath_arch, state, self._payload, self.i, self.o, self.dsp,
              self.max_dsp)
        return m
