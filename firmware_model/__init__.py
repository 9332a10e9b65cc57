"""The Nios-style integer C solver (``ik5r.c``), its generated header, and its bit-accurate models."""
