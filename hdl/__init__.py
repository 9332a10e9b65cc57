"""Amaranth hardware of the ik5r fixed-point arithmetic, bit-exact to ``firmware_model/model.py``.

Blocks (each a :class:`amaranth.lib.wiring.Component` with ``i``/``o`` valid/ready streams):
:class:`ik5r.hdl.blocks.cordic.Atan2`, :class:`ik5r.hdl.blocks.cordic.Rotate`, :class:`ik5r.hdl.blocks.sqrt.Sqrt`,
:class:`ik5r.hdl.blocks.acos.Acos`; the IK core :class:`ik5r.hdl.pipelined.core.IKCore`; Verilog and port maps:
:func:`ik5r.hdl.generate.generate`.

This package imports nothing itself (no Amaranth), so that the simulator's Python loads the
testbench ``ik5r.tools.testbench.stream_tb`` quickly: import the submodules.
"""
