"""The sequenced IK engine (the compact core): its instruction set, the lowering and scheduling of
the traced graph into its program, and the engine itself."""
