"""The datapath of stages every block and core is described in (:mod:`.stages`), its two elaborations
(:mod:`.build`), the expression helpers, multipliers, ECP5 primitives and the stash."""
