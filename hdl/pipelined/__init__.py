"""The pipelined IK core (and its staged elaboration), generated from the traced graph."""
