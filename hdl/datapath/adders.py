"""The add/subtract mapping of a datapath: portable operators, or ECP5 ``CCU2C`` chains that the
pipelined build places stage by stage (:attr:`~.stages.Datapath.adders`)."""

from __future__ import annotations

from ik5r.core.modes import DSPS, Dsp

from .expr import add_sub

__all__ = ["GenericAdders", "Ecp5Adders", "adders_for"]


class GenericAdders:
    """``add_sub`` as portable operators (any FPGA, any architecture)."""
    dsp = Dsp.GENERIC

    def add_sub(self, a, b, subtract):
        return add_sub(a, b, subtract)

    def take(self) -> list:
        return []


class Ecp5Adders:
    """``add_sub`` as ECP5 ``CCU2C`` chains, collected until the pipelined build takes them for
    the stage being built (:meth:`take`). While :attr:`tracing` (the construction check) it
    builds the generic adder of the same shape and collects nothing."""
    dsp = Dsp.ECP5

    def __init__(self):
        self.pending = []
        self.tracing = False

    def add_sub(self, a, b, subtract):
        return add_sub(a, b, subtract, chains=None if self.tracing else self.pending)

    def take(self) -> list:
        chains, self.pending = self.pending, []
        return chains


def adders_for(dsp: str):
    """The add/subtract mapping of a datapath built with ``dsp`` (one of :data:`DSPS`)."""
    if dsp not in DSPS:
        raise ValueError(f"dsp must be one of {DSPS}, got {dsp!r}")
    return Ecp5Adders() if dsp == Dsp.ECP5 else GenericAdders()
