"""The add/subtract mapping of a datapath: portable operators, or ECP5 ``CCU2C`` chains that the
pipelined build places stage by stage (:attr:`~.stages.Datapath.adders`)."""

from __future__ import annotations

from ik5r.core.modes import DSP_OUTPUT_REGS, DSPS, Dsp

from .expr import add_sub

__all__ = ["GenericAdders", "Ecp5Adders", "adders_for"]


class GenericAdders:
    """``add_sub`` as portable operators (any FPGA, any architecture)."""
    dsp = Dsp.GENERIC
    dsp_output_regs = 0

    def add_sub(self, a, b, subtract):
        return add_sub(a, b, subtract)

    def take(self) -> list:
        return []


class Ecp5Adders:
    """``add_sub`` as ECP5 ``CCU2C`` chains, collected until the pipelined build takes them for
    the stage being built (:meth:`take`). While :attr:`tracing` (the construction check) it
    builds the generic adder of the same shape and collects nothing. ``dsp_output_regs``:
    registers in the fabric after each DSP's own output register (:func:`~.products.add_products`).
    """
    dsp = Dsp.ECP5

    def __init__(self, dsp_output_regs: int = 0):
        self.pending = []
        self.tracing = False
        self.dsp_output_regs = dsp_output_regs

    def add_sub(self, a, b, subtract):
        return add_sub(a, b, subtract, chains=None if self.tracing else self.pending)

    def take(self) -> list:
        chains, self.pending = self.pending, []
        return chains


def adders_for(dsp: str, dsp_output_regs: int = 0):
    """The add/subtract mapping of a datapath built with ``dsp`` (one of :data:`DSPS`), with
    ``dsp_output_regs`` (one of :data:`DSP_OUTPUT_REGS`; ECP5 only) fabric registers after each
    DSP."""
    if dsp not in DSPS:
        raise ValueError(f"dsp must be one of {DSPS}, got {dsp!r}")
    if type(dsp_output_regs) is not int or dsp_output_regs not in DSP_OUTPUT_REGS:
        raise ValueError(f"dsp_output_regs must be one of {DSP_OUTPUT_REGS}, got {dsp_output_regs!r}")
    if dsp_output_regs and dsp != Dsp.ECP5:
        raise ValueError(f"dsp_output_regs applies to dsp={Dsp.ECP5.value!r}, got dsp={dsp!r}")
    return Ecp5Adders(dsp_output_regs) if dsp == Dsp.ECP5 else GenericAdders()
