"""The top layer: the command line (``cli``, ``commands``), synthesis and sweeps, benches, the
report and the README results, the soft-CPU runs and the cocotb testbenches (``testbench``), which
check the HDL against the firmware model. Nothing below imports it."""
