"""Generic cocotb stream testbench of the ik5r HDL blocks (``ik5r sim`` and tests/test_cocotb_blocks.py).

- :mod:`.portmap`    port map JSON -> ports, payload fields, packing / unpacking
- :mod:`.blocks`     per-block reference models (bit-accurate), float references, edge sets
- :mod:`.wrapper`    generated Verilog wrapper: cocotb-driven stream ports + a fast bulk mode
- :mod:`.stream_tb`  the cocotb test module (the stream test and the bulk test)
- :mod:`.job`        the run's job JSON, stimulus, expected values (the model), result counts
- :mod:`.components` Driver, Monitor, back-pressure, reset, in-order scoreboard, the clocked loop
- :mod:`.serial`     beat driver and monitor of the compact IK core's word-serial wrapper
- :mod:`.bulk`       the bulk test's chunks through the wrapper's engine
- :mod:`.runner`     build and run through ``cocotb_tools.runner``
- :mod:`.harness`    the fast bulk path without cocotb: a Verilator C++ main (``harness.cpp``) fed
                     from a file of words, outputs compared with the model in numpy
"""
