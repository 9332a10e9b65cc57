"""The Verilog text the bulk harness verilates: the design's Verilog with each run of one repeated
bit in a concatenation written as a replication.

Yosys writes a replicated bit out one copy at a time (``{ cy[44], cy[44], ... }``), and the
inverted copies as one-bit wires of their own (``assign \\$10520 = ~ cy[44];`` forty-six times, then
``{ \\$10539 , \\$10538 , ... }``). Verilator compiles every copy into a shift, a mask and an OR, so
in the pipelined IK core these runs are most of the C++ it evaluates per clock. IEEE 1364-2005
5.1.14 defines ``{n{x}}`` as the concatenation of ``n`` copies of ``x``, so
``{46{~ cy[44]}}`` is the same expression; Verilator compiles it as one sign mask.

Only what is provably the same bit is merged: a run of textually equal items that each name one
bit of a plain identifier (``name[k]``), or of one-bit wires assigned ``~ name[k]``. Every other
item and every other line is kept byte for byte; the synthesised Verilog is not touched.
"""

from __future__ import annotations

import re

#: ``assign \$N = ~ name[k];``: a wire that is the inverse of one bit (an alias only when the
#: wire is one bit wide: a wider one holds the inverse of the zero-extended bit).
_INVERTED = re.compile(r"^\s*assign (\\\$\d+)\s+= (~ [A-Za-z_][A-Za-z0-9_$]*\[\d+\]);$", re.M)
#: ``wire \$N ;``: a one-bit wire (no range).
_ONE_BIT = re.compile(r"^\s*wire (\\\$\d+) ;$", re.M)
#: One bit of a plain (not escaped) identifier, or its inverse.
_BIT = re.compile(r"~ ?[A-Za-z_][A-Za-z0-9_$]*\[\d+\]|[A-Za-z_][A-Za-z0-9_$]*\[\d+\]")
#: A concatenation without nested braces, as yosys writes it (a space inside each brace).
_CONCAT = re.compile(r"\{ ([^{}]*) \}")


def _merge(items: list[str], alias: dict[str, str]) -> tuple[list[str], int]:
    """The items with each run of one bit (after the aliases) as a replication; runs merged."""
    bits = [alias.get(item, item) for item in items]
    out, runs, j = [], 0, 0
    while j < len(bits):
        k = j
        while k + 1 < len(bits) and bits[k + 1] == bits[j]:
            k += 1
        if k > j and _BIT.fullmatch(bits[j]):
            # Spaces around the item: an escaped identifier ends at white space.
            out.append(f"{{{k - j + 1}{{ {bits[j]} }}}}")
            runs += 1
        else:
            out.extend(items[j:k + 1])
        j = k + 1
    return out, runs


def replicate_runs(text: str) -> tuple[str, int]:
    """(``text`` with every run of one repeated bit in a concatenation as ``{n{bit}}``, the number
    of runs merged)."""
    one_bit = set(_ONE_BIT.findall(text))
    alias = {wire: inverse for wire, inverse in _INVERTED.findall(text) if wire in one_bit}
    total = 0

    def concat(m: re.Match) -> str:
        nonlocal total
        items = [s.strip() for s in m.group(1).split(",")]
        out, runs = _merge(items, alias)
        if not runs:
            return m.group(0)
        total += runs
        return "{ " + " , ".join(out) + " }"

    return _CONCAT.sub(concat, text), total
