"""The soft-CPU system on chip (VexRiscv + RAM) the C solver runs on."""
