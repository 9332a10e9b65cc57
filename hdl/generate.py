"""Verilog of the ik5r blocks and their port maps (the contract of the cocotb testbenches).

``generate(block, arch, constants, tag_width) -> (verilog_text, portmap)``. The module is named
``ik5r_<block>_<arch>`` (e.g. ``ik5r_atan2_pipelined``); the text is deterministic (no source
locations, no paths, no time stamps) so two runs give byte-identical files. It starts with a
header comment (:mod:`.provenance`: config, formats, latency, error bound, tool versions, source
commit); hashes of the design are of the text without it (:func:`.provenance.body_sha256`).

Amaranth flattens each stream of the component into ports named ``<stream>__<member>``:
``i__payload``, ``i__valid``, ``i__ready``, ``o__payload``, ``o__valid``, ``o__ready``, plus the
clock ``clk`` and the synchronous, active-high reset ``rst``. A payload port is the struct
layout's bits: the first field at bit 0. The port map records every port and every payload
field's bit range, signedness and fraction bits.
"""

from __future__ import annotations

from amaranth.back import verilog
from amaranth.hdl import Shape
from amaranth.lib import wiring

from ik5r.core.fxconfig import Constants
from ik5r.core.modes import ARCHS, BLOCKS, CORE_ARCHS, Arch, Block, CoreArch

from .datapath.ecp5 import ECP5_ADD_SUB_MODULE, ecp5_add_sub_verilog
from .provenance import arm_hash, verilog_header

__all__ = ["BLOCKS", "ARCHS", "archs_of", "resolve_arch", "module_name", "build", "generate", "portmap"]

# BLOCKS: the names :func:`generate` and the ``ik5r verilog`` verb accept (``ik`` is the IK core);
# CORE_ARCHS the IK core's architectures, ARCHS the arithmetic blocks' (all in .modes).


def archs_of(block: str) -> tuple[str, ...]:
    """The architectures ``block`` comes in: (the fast one, the small one)."""
    return CORE_ARCHS if block == Block.IK else ARCHS


def resolve_arch(block: str, arch: str) -> str:
    """``arch`` for ``block``, where ``iterative`` and ``compact`` both name the small one."""
    archs = archs_of(block)
    if arch in archs:
        return arch
    if arch in (Arch.ITERATIVE, CoreArch.COMPACT):
        return archs[1]
    raise ValueError(f"{block}: arch must be one of {archs}, got {arch!r}")

#: Version of the port-map JSON layout.
PORTMAP_VERSION = 1


def module_name(block: str, arch: str, **options) -> str:
    """``ik5r_<block>_<arch>``; non-default options are named in between, e.g.
    ``ik5r_sqrt_radicand_bits64_pipelined``."""
    suffix = "".join(f"_{key}{int(value) if isinstance(value, bool) else value}"
                     for key, value in sorted(options.items()) if value is not None)
    return f"ik5r_{block}{suffix}_{arch}"


def build(block: str, arch: str, constants: Constants, tag_width: int = 0, **options):
    """The Amaranth component of ``block`` (options: ``magnitude`` for atan2, ``frac`` or
    ``radicand_bits`` for sqrt; defaults: magnitude on, sqrt of a length word)."""
    if block == Block.ATAN2:
        from .blocks.cordic import Atan2
        return Atan2(constants=constants, arch=arch, tag_width=tag_width,
                     magnitude=options.pop("magnitude", True), **options)
    if block == Block.ROTATE:
        from .blocks.cordic import Rotate
        return Rotate(constants=constants, arch=arch, tag_width=tag_width, **options)
    if block == Block.SQRT:
        from .blocks.sqrt import Sqrt
        return Sqrt(constants=constants, arch=arch, tag_width=tag_width, **options)
    if block == Block.ACOS:
        from .blocks.acos import Acos
        return Acos(constants=constants, arch=arch, tag_width=tag_width, **options)
    if block == Block.IK:
        if arch == CoreArch.COMPACT:
            from .sequenced.engine import SequencedIKCore
            from .sequenced.serial import SerialIK
            serial = options.pop("serial", None)
            if serial:
                return SerialIK(constants=constants, tag_width=tag_width, beat_bits=serial, **options)
            return SequencedIKCore(constants=constants, tag_width=tag_width, **options)
        from .pipelined.core import IKCore
        return IKCore(constants=constants, arch=arch,
                      tag_width=tag_width, **options)
    raise ValueError(f"block must be one of {BLOCKS}, got {block!r}")


def _fields(fields: dict) -> list:
    out, lsb = [], 0
    for name, (shape, frac, description) in fields.items():
        shape = Shape.cast(shape)
        out.append({
            "name": name,
            "lsb": lsb,
            "msb": lsb + shape.width - 1,
            "width": shape.width,
            "signed": shape.signed,
            "frac": frac,
            "description": description,
        })
        lsb += shape.width
    return out


_CLOCK_PORTS = ({"name": "clk", "direction": "input", "width": 1, "role": "clock, rising edge"},
                {"name": "rst", "direction": "input", "width": 1, "role": "synchronous reset, active high"})


def _port(path, is_input: bool, width: int) -> dict:
    return {"name": "__".join(map(str, path)), "direction": "input" if is_input else "output", "width": width,
            "role": {"payload": "payload (struct, fields below)", "valid": "stream valid",
                     "ready": "stream ready"}[path[-1]] + f" of stream {path[0]}"}


def stream_ports(in_fields: dict, out_fields: dict) -> tuple[list, dict]:
    """(ports, streams) of the port map of a component with an input stream ``i`` and an output
    stream ``o`` of these payload fields, as :func:`portmap` lists them, without the component
    (the word-level view of a wrapper, whose core need not be built for it)."""
    ports = [dict(p) for p in _CLOCK_PORTS]
    streams = {}
    for stream, fields, is_input in (("i", in_fields, True), ("o", out_fields, False)):
        width = sum(Shape.cast(shape).width for shape, _, _ in fields.values())
        ports += [_port((stream, "payload"), is_input, width), _port((stream, "valid"), is_input, 1),
                  _port((stream, "ready"), not is_input, 1)]
        streams[stream] = {"payload": f"{stream}__payload", "valid": f"{stream}__valid",
                           "ready": f"{stream}__ready", "fields": _fields(fields)}
    return ports, streams


def portmap(component, block: str, arch: str, constants: Constants, name: str | None = None) -> dict:
    """The port map of a component (see the module docstring); ``name``: its module name."""
    c = constants.cfg
    ports = [dict(p) for p in _CLOCK_PORTS]
    for path, member, value in component.signature.flatten(component):
        ports.append(_port(path, member.flow == wiring.In, Shape.cast(member.shape).width))
    doc = {
        "version": PORTMAP_VERSION,
        "module": name or module_name(block, arch),
        "block": block,
        "arch": arch,
        "config": c.name,
        "config_params": {
            "width": c.width, "frac_length": c.frac_length, "frac_unit": c.frac_unit,
            "frac_angle": c.frac_angle, "iterations": c.iterations, "guard_bits": c.guard_bits,
            "angle_guard_bits": c.angle_guard_bits, "rounding": c.rounding,
        },
        "arm": {"name": constants.arm.name, "sha256": arm_hash(constants),
                "reach_cm": constants.arm.reach},
        "tag_width": component.tag_width,
        "latency_cycles": component.latency,
        "cycles_per_result": component.cycles_per_result,
        "clock": "clk",
        "reset": "rst",
        "ports": ports,
        "streams": {
            "i": {"payload": "i__payload", "valid": "i__valid", "ready": "i__ready",
                  "fields": _fields(component.in_fields)},
            "o": {"payload": "o__payload", "valid": "o__valid", "ready": "o__ready",
                  "fields": _fields(component.out_fields)},
        },
        "options": dict(getattr(component, "options", {})),
        "model": {Block.ATAN2: "model.cordic_atan2", Block.ROTATE: "model.cordic_rotate",
                  Block.SQRT: "model.sqrt_word / model.isqrt", Block.ACOS: "model.cordic_acos",
                  Block.IK: "model.ik_solve"}[block],
        "notes": ("Handshake: a transfer happens on a rising clk edge with valid & ready high. "
                  "Output o stays valid and stable until taken. frac = null: the field takes "
                  "any format common to the fields so marked."),
    }
    return doc


def generate(block: str, arch: str, constants: Constants, tag_width: int = 0, **options):
    """Verilog text and port-map dict of one block; deterministic (see the module docstring).

    ``options`` go to the block's constructor (``magnitude=False`` for atan2, ``frac=`` or
    ``radicand_bits=`` for sqrt) and into the module name when given.
    """
    if arch not in archs_of(block):
        raise ValueError(f"{block}: arch must be one of {archs_of(block)}, got {arch!r}")
    name = module_name(block, arch, **options)
    header_options = dict(options)
    component = build(block, arch, constants, tag_width, **options)
    pmap = portmap(component, block, arch, constants, name)
    text = verilog.convert(component, name=name, emit_src=False, strip_internal_attrs=True)
    if f"{ECP5_ADD_SUB_MODULE} #(" in text:
        text += ecp5_add_sub_verilog()
    return verilog_header(pmap, constants, header_options) + text, pmap
