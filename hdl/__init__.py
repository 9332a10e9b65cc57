"""Amaranth hardware of the ik5r fixed-point arithmetic, bit-exact to ``firmware_model/model.py``.

Blocks (each a :class:`amaranth.lib.wiring.Component` with ``i``/``o`` valid/ready streams):
:class:`Atan2`, :class:`Rotate`, :class:`Sqrt`, :class:`Acos`; Verilog and port maps:
:func:`ik5r.hdl.generate.generate`.
"""

from .common import ARCHS
from .acos import Acos
from .cordic import Atan2, Rotate
from .sqrt import Sqrt

__all__ = ["ARCHS", "Acos", "Atan2", "Rotate", "Sqrt"]
