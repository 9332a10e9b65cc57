"""Numeric IK of any serial arm in float64 (above the core, beside the firmware and the HDL):
Levenberg-Marquardt on the analytic Jacobian (``solver``), its C kernel (``lmkernel``, ``csrc/``),
many seeded starts per pose (``multistart``) and the task-space start table (``start_table``)."""
