"""Formal checks of the stream contract of every ik5r block and IK core (SymbiYosys).

:mod:`.contract`: the properties (Amaranth ``Assert``/``Assume``) around a real component whose
datapath values are abstracted to free values; :mod:`.run`: the SymbiYosys jobs
(``python -m ik5r.hdl.formal``, ``make formal``).
"""
