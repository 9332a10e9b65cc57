"""Composing chains (:class:`~ik5r.hdl.datapath.stages.Datapath` s with their own key names) into one
datapath, as the IK core does with the blocks' chains:

* **Namespaces.** :func:`namespaced` wraps a chain's stages so that they see and produce only
  the keys under a prefix (``T1__cx`` ...), without it; declared register shapes are copied with
  the prefix.
* **Parallel chains.** :func:`append_chains` runs several chains side by side in the same
  stages: their iterated stages (micro-rotations, square-root digits) are aligned, the
  non-iterated stages before / between / after them are padded with pass-through stages, and the
  stage functions of one cycle are composed (each chain reads only its own keys). An iterated
  stage shorter than its partners is frozen by a step guard, so both architectures work. In a
  datapath that shares its functional units the chains run one after the other instead.
* **Selecting stages.** :func:`add_selecting`: a stage whose values are selected by compares,
  registered a stage earlier in the pipelined core.
"""

from __future__ import annotations

from amaranth.hdl import Mux

from ..datapath.stages import Datapath
from ..datapath.tracing import retraced, traced_view
from ..datapath.expr import drop

__all__ = ["namespaced", "concat", "compose", "append_chains", "add_selecting"]


def namespaced(chain: Datapath, prefix: str) -> Datapath:
    """``chain``'s stages seeing only the keys under ``prefix`` (without it); others pass through."""
    size = len(prefix)
    out = Datapath(chain.name, adders=chain.adders, inputs=[prefix + key for key in chain.inputs],
                   outputs=[prefix + key for key in chain.outputs])
    out.shapes = {prefix + key: shape for key, shape in chain.shapes.items()}

    def split(s):
        inner = traced_view(s, {key[size:]: key for key in s if key.startswith(prefix)})
        outer = {key: dict.__getitem__(s, key) for key in s if not key.startswith(prefix)}
        return inner, outer

    for stage in chain.stages:
        fn = stage.fn
        if stage.iterated:
            def run(s, i, fn=fn):
                inner, outer = split(s)
                outer.update({prefix + key: value for key, value in fn(inner, i).items()})
                return outer
            shared = None if stage.shared is None else stage.shared.prefixed(prefix)
            if shared is not None:
                run.shared = shared
        else:
            def run(s, fn=fn):
                inner, outer = split(s)
                outer.update({prefix + key: value for key, value in fn(inner).items()})
                return outer
            shared = None
        out.append(stage.with_fn(run, name=f"{prefix.rstrip('_').lower()}_{stage.name}", shared=shared))
    return out


def concat(name: str, *chains: Datapath) -> Datapath:
    out = Datapath(name, adders=chains[0].adders)
    for chain in chains:
        out.stages.extend(chain.stages)
        out.shapes.update(chain.shapes)
    return out


def compose(*fns):
    def run(s):
        for fn in fns:
            s = retraced(fn(s), s)
        return s
    return run


def _segments(chain: Datapath):
    """[N0, (I1), N1, (I2), ...]: lists of registered stage functions between iterated stages
    ``(fn, count)``. Wiring stages are folded into a neighbouring registered stage (after the
    previous one, else before the next one, else made a registered stage of their own)."""
    items = []     # ("N", fn) | ("I", fn, count) | ("W", fn)
    for stage in chain.stages:
        fn, count = stage.fn, stage.count
        items.append(("I", fn, count) if stage.iterated else ("W", fn) if count == 0 else ("N", fn))
    folded = []
    pending = []
    for item in items:
        if item[0] == "W":
            if folded and folded[-1][0] == "N" and not pending:
                folded[-1] = ("N", compose(folded[-1][1], item[1]))
            else:
                pending.append(item[1])
            continue
        if pending:
            if item[0] == "N":
                item = ("N", compose(*pending, item[1]))
            else:
                folded.append(("N", compose(*pending)))
            pending = []
        folded.append(item)
    if pending:
        folded.append(("N", compose(*pending)))
    segments = [[]]
    for item in folded:
        if item[0] == "N":
            segments[-1].append(item[1])
        else:
            segments.append((item[1], item[2]))
            segments.append([])
    return segments


def _guarded(fn, count):
    """An iterated stage function frozen once ``i >= count``."""
    def run(s, i):
        if isinstance(i, int):
            return fn(s, i) if i < count else s
        out = fn(s, i)
        active = i < count
        return {key: value if key not in s or value is dict.__getitem__(s, key) else Mux(active, value, s[key])
                for key, value in out.items()}
    return run


def append_chains(dp: Datapath, name: str, *chains: Datapath) -> None:
    """Append ``chains`` to ``dp``: side by side (see the module docstring), or one after the
    other in a datapath that shares its functional units (``share_units``: the chains' CORDIC
    steps then run on one unit)."""
    if not dp.share_units:
        _append_parallel(dp, name, *chains)
        return
    for chain in chains:
        dp.declare(**chain.shapes)
        dp.stages.extend(stage.with_fn(stage.fn, name=f"{name}_{stage.name}", shared=stage.shared)
                         for stage in chain.stages)


def _append_parallel(dp: Datapath, name: str, *chains: Datapath) -> None:
    """Append ``chains`` to ``dp`` side by side (see the module docstring)."""
    segs = [_segments(chain) for chain in chains]
    for chain in chains:
        dp.declare(**chain.shapes)
    depth = max(len(seg) for seg in segs)
    # A chain with fewer iterated stages waits in front: pass-through iterated stages are
    # prepended, so its loops run beside its partners' last ones.
    segs = [[[], (lambda s, i: s, 1)] * ((depth - len(seg)) // 2) + seg for seg in segs]
    for index in range(depth):
        if index % 2 == 0:
            lists = [seg[index] for seg in segs]
            length = max(len(fns) for fns in lists)
            for t in range(length):
                fns = []
                for fns_c in lists:
                    # Pad the first segment at the front (inputs wait), the others at the end.
                    pos = t - (length - len(fns_c)) if index == 0 else t
                    if 0 <= pos < len(fns_c):
                        fns.append(fns_c[pos])
                dp.add(f"{name}_{index}_{t}", compose(*fns))
        else:
            count = max(seg[index][1] for seg in segs)
            fns = [fn if c == count else _guarded(fn, c) for fn, c in (seg[index] for seg in segs)]

            def iterated(s, i, fns=fns):
                for fn in fns:
                    s = retraced(fn(s, i), s)
                return s
            dp.add_iter(f"{name}_it{index}", iterated, count)



def add_selecting(dp: Datapath, name: str, compares: dict, fn, *, registered: bool) -> None:
    """Stage ``name``: ``fn(state, flags)`` with ``flags[key] = compares[key](state)``, the
    compares that select its values.

    ``registered`` (the pipelined core): the compares run one stage earlier, in ``name_cmp``, and
    reach ``fn`` from registers. On ECP5 a compare's carry chain followed by a select as wide as
    the word was the pipelined core's critical path (see the records in docs/results/records);
    split, each stage is one carry chain or one select behind a register.
    """
    if not registered:
        dp.add(name, lambda s: fn(s, {key: compare(s) for key, compare in compares.items()}))
        return
    keys = {key: f"{name}_{key}" for key in compares}
    dp.add(f"{name}_cmp", lambda s: dict(s, **{keys[key]: compare(s)
                                               for key, compare in compares.items()}))
    dp.add(name, lambda s: fn(drop(s, *keys.values()), {key: s[keys[key]] for key in keys}))

