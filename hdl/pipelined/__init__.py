"""The pipelined IK core, generated from the traced graph."""
