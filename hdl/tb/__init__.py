"""Generic cocotb stream testbench of the ik5r HDL blocks (``ik5r sim`` and tests/test_cocotb_blocks.py).

- :mod:`.portmap`  port map JSON -> ports, payload fields, packing / unpacking
- :mod:`.blocks`   per-block reference models (bit-accurate), float references, edge sets
- :mod:`.wrapper`  generated Verilog wrapper: cocotb-driven stream ports + a fast bulk mode
- :mod:`.stream_tb` the cocotb test module (Driver, Monitor, back-pressure, reset, scoreboard)
- :mod:`.runner`   build and run through ``cocotb_tools.runner``
"""
