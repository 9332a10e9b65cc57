"""ik5r: inverse kinematics of a 5R arm, from a float64 reference to bit-exact FPGA hardware."""

__version__ = "0.1.0"
