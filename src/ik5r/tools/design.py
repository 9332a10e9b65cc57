"""The design point of the hardware path, resolved once: block, arch, config, arm and options.

Every fixed-point command (``verilog``, ``sim``, ``synth``, ``report --hdl``, ``firmware``,
``sweep``) turns its ``--block/--arch/--config/--arm/...`` into one frozen :class:`Design`
(:meth:`Design.resolve`, :func:`from_args`) and passes it down. Resolving it loads the config
and the arm once and builds their :class:`~ik5r.core.fxconfig.Constants`, which refuses an arm
the config's formats cannot hold (:mod:`ik5r.core.armfit`): nothing is generated for it.

:meth:`Design.verilog` is the one way to the Verilog and the port map (cached on disk by
:func:`ik5r.tools.verilog_cache.generate_cached`). The arm is part of the design point: its
name and numbers are in the Verilog header and the port map (``arm``), the caches' keys, and the
names of records (:attr:`Design.arm_suffix`: empty for the arm of record, so its records keep
their names).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

from ik5r.core.arm import Arm, is_seed_arm, load_arm
from ik5r.core.fxconfig import Constants, FixedConfig, load_config
from ik5r.core.modes import Dsp


@dataclass(frozen=True)
class DesignOptions:
    """What else shapes the Verilog: the tag field, the multipliers, the word-serial wrapper."""

    tag_width: int = 0
    dsp: str = Dsp.GENERIC          # core.modes.DSPS; only the pipelined arch maps primitives
    serial: int | None = None       # compact IK core: beats of its word-serial wrapper
    rotations_per_stage: int = 1    # pipelined arch: CORDIC micro-rotations per register stage
    max_dsp: int | None = None      # pipelined arch, dsp="ecp5": cap on MULT18X18D (the rest in LUTs)
    wide_product: bool = False      # compact IK core: a 16 x 31 product step (two DSPs), fewer clocks
    dsp_output_regs: int = 0        # pipelined IK core, dsp="ecp5": fabric registers after each DSP
    poses: int = 1                  # compact IK core: poses a program (2: two share the units)

    def generate_kwargs(self) -> dict:
        """The options of ``ik5r.hdl.generate.generate`` (module name, constructor)."""
        return ({} if self.dsp == Dsp.GENERIC else {"dsp": self.dsp}) | \
               ({} if self.serial is None else {"serial": self.serial}) | \
               ({} if self.rotations_per_stage == 1 else {"rotations_per_stage": self.rotations_per_stage}) | \
               ({} if self.max_dsp is None else {"max_dsp": self.max_dsp}) | \
               ({"wide_product": True} if self.wide_product else {}) | \
               ({"dsp_output_regs": self.dsp_output_regs} if self.dsp_output_regs else {}) | \
               ({"poses": self.poses} if self.poses != 1 else {})


@dataclass(frozen=True)
class Design:
    """One design point. Build it with :meth:`resolve`; ``arch`` is already resolved."""

    block: str
    arch: str
    config: FixedConfig
    arm: Arm
    options: DesignOptions = field(default_factory=DesignOptions)

    @classmethod
    def resolve(cls, block: str, arch: str, *, config: FixedConfig | str | Path | None = None,
                arm: Arm | str | Path | None = None, tag_width: int = 0, dsp: str = Dsp.GENERIC,
                serial: int | None = None, rotations_per_stage: int = 1,
                max_dsp: int | None = None, wide_product: bool = False,
                dsp_output_regs: int = 0, poses: int = 1) -> "Design":
        """Load the config (name or file) and the arm (name or file) once, resolve the arch
        (``iterative``/``compact``: the small one) and check the arm fits the config."""
        from ik5r.hdl.generate import resolve_arch

        cfg = config if isinstance(config, FixedConfig) else load_config(config)
        arm_ = arm if isinstance(arm, Arm) else load_arm(arm)
        if block not in ("cpu",):
            arch = resolve_arch(block, arch)
        design = cls(block, arch, cfg, arm_, DesignOptions(tag_width, dsp, serial, rotations_per_stage,
                                                          max_dsp, wide_product, dsp_output_regs, poses))
        design.constants        # noqa: B018 -- builds and checks (armfit) now, not at generation
        return design

    @cached_property
    def constants(self) -> Constants:
        return Constants(self.config, self.arm)

    @cached_property
    def arm_is_seed(self) -> bool:
        return is_seed_arm(self.arm)

    @property
    def arm_suffix(self) -> str:
        """``""`` for the arm of record, else ``_arm-<name>``: in record and folder names."""
        return "" if self.arm_is_seed else f"_arm-{self.arm.name}"

    @property
    def config_label(self) -> str:
        """The config's name, with the arm's unless it is the arm of record (``q32w_arm-al5d``)."""
        return self.config.name + self.arm_suffix

    def verilog(self) -> tuple[str, dict]:
        """The Verilog text (header included) and the port map, from the on-disk cache."""
        from .verilog_cache import generate_cached

        return generate_cached(self.block, self.arch, self.constants, self.options.tag_width,
                               **self.options.generate_kwargs())


def add_arm_argument(parser) -> None:
    """``--arm ARM.toml|NAME`` of every fixed-point verb."""
    parser.add_argument("--arm", default=None, metavar="ARM",
                        help="arm TOML or shipped arm name (ik5r arms; default: the arm of record, hu-5r)")
