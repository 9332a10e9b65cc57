"""The ``order`` group of an iterative build (the iterative blocks) by
k-induction.

An iterative build (:func:`~ik5r.hdl.datapath.build.build_iterative`) holds one item: a stage's
``<stage>_valid`` bit says the item is in it, and with no output held it moves on as soon as
the stage is done: a registered stage after one cycle, an iterated one after ``count`` (its
``<stage>_step``, or the ``unit_<unit>_step`` of the functional unit it shares, counts 1 ..
``count``). So the item is, ``w`` cycles after its input transfer (``w`` + 1 cycles, counted as
the marks' ``waiting``, see :meth:`.contract.StreamContract._marks`), in the stage ``s`` with
``base(s) <= w < base(s) + count(s)`` (``base``: the register stages before ``s``) at step
``w - base(s) + 1``, until the last stage is done and it waits on ``o``.

Its tag is in the tag register of the nearest stage at or before ``s`` that has one: every
stage's registers are loaded only when the item enters it, and one item is inside, so they
hold until the next item. That register is ``s``'s own, or an earlier one where the tag is not
in the stage's state: a shared unit's stage carries only the unit's values (the others stay in
the stage before).

:func:`track_item` asserts that, for each mark: in an occupied stage the tag is the mark iff
the mark is inside, the tag is never 3, a mark inside has an occupied stage, and while it is
inside and not yet on ``o`` ``waiting`` is its place in the stage sequence. With the
``conservation`` group (at most one stage occupied) these make the marks' assertions
inductive (nothing here is assumed).
"""

from __future__ import annotations

from amaranth.hdl import Cat, Module

from ..datapath.stages import Stage

__all__ = ["track_item"]


def _places(dut, inner: Module, find) -> list:
    """(valid, tag, position) of every stage: position = the item's ``waiting`` there."""
    dp, places, base, tag = dut._dp, [], 0, None
    for stage in map(Stage.of, dp.stages):
        if stage.count == 0:
            continue
        try:
            tag = find(inner, f"{stage.name}_tag")
        except LookupError:
            if tag is None:
                raise ValueError(f"stage {stage.name!r}: no tag register at or before it")
        valid = find(inner, f"{stage.name}_valid")
        if not stage.iterated:
            position, step = base, None
        else:
            shared = stage.shared if dp.share_units else None
            step = find(inner, f"unit_{shared.unit}_step" if shared else f"{stage.name}_step")
            position = base + step - 1
        places.append((valid, tag, position, step, stage.count))
        base += stage.count
    return places


def track_item(m, dut, inner, find, marks, o_valid, check):
    """Assert (``check(test, name)``) where the item and its mark are (module docstring).
    ``marks``: {mark: (sent, got)} and ``"waiting"`` (:meth:`.contract.StreamContract._marks`)."""
    places = _places(dut, inner, find)
    waiting = marks["waiting"]
    unused = (1 << len(places[0][1])) - 1
    occupied = Cat(*(valid for valid, *_ in places)).any()
    last_valid = places[-1][0]
    for valid, tag, position, step, count in places:
        with m.If(valid):
            m.d.comb += check(tag != unused, "mark_invented")
            if step is not None:
                m.d.comb += check((step >= 1) & (step <= count), "item_step")
    for mark in (1, 2):
        sent, got = marks[mark]
        inside = sent & ~got
        m.d.comb += check(~got | sent, "mark_got_sent")
        m.d.comb += check(~inside | occupied, "mark_occupied")
        for valid, tag, position, step, count in places:
            with m.If(valid):
                m.d.comb += check((tag == mark) == inside, "mark_stage")
            if mark == 1:
                # A's place in the sequence: the cycles it has waited (0 once it is on o).
                on_o = (valid is last_valid) & o_valid & (waiting == 0)
                with m.If(valid & inside):
                    m.d.comb += check((waiting == position) | on_o, "mark_waiting")
    (sent_a, got_a), (sent_b, got_b) = marks[1], marks[2]
    m.d.comb += [
        check(~sent_b | sent_a, "mark_sent_order"),
        check(~got_b | got_a, "mark_got_order"),
    ]
