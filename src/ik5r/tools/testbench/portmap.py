"""Port maps of generated stream blocks, and payload packing / unpacking from them.

A port map is the JSON that ``ik5r verilog`` writes next to each ``.v``: every top-level port with
its direction and width, every payload field's bit range within the flattened payload port (its
signedness and fraction bits), and the block's ``latency_cycles`` / ``cycles_per_result``.

The loader is tolerant about spelling (``dir``/``direction``, ``lsb``/``offset``/``start``, ports
as a dict or a list, fields as a dict or a list) so that the testbench does not need to change
when the generator's JSON grows a key; :class:`PortMap` is the normalised form.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class Field:
    name: str
    lsb: int
    width: int
    signed: bool = True
    frac: int | None = None

    @property
    def mask(self) -> int:
        return (1 << self.width) - 1

    def to_raw(self, value: int) -> int:
        """A field value (Python int, in range) to its unsigned bits."""
        return int(value) & self.mask

    def from_raw(self, raw: int) -> int:
        raw = int(raw) & self.mask
        if self.signed and raw >> (self.width - 1):
            raw -= 1 << self.width
        return raw

    @property
    def lo(self) -> int:
        return -(1 << (self.width - 1)) if self.signed else 0

    @property
    def hi(self) -> int:
        return (1 << (self.width - 1)) - 1 if self.signed else (1 << self.width) - 1


@dataclass(frozen=True)
class Port:
    name: str
    direction: str   # "input" / "output"
    width: int


@dataclass
class Stream:
    """One valid/ready stream side: its three ports and the payload's fields."""

    valid: str
    ready: str
    payload: str
    width: int
    fields: dict[str, Field] = field(default_factory=dict)

    def pack(self, values: dict[str, int]) -> int:
        word = 0
        for name, f in self.fields.items():
            word |= f.to_raw(values[name]) << f.lsb
        return word

    def unpack(self, word: int) -> dict[str, int]:
        return {name: f.from_raw(int(word) >> f.lsb) for name, f in self.fields.items()}

    # ---- vectorised, for the bulk mode -------------------------------------------------------
    def pack_words(self, columns: dict[str, np.ndarray]) -> np.ndarray:
        """Pack N items (one int array per field) to an (N, ceil(width/32)) uint32 array of
        little-endian 32-bit limbs (bits above the width zero)."""
        count = len(next(iter(columns.values())))
        limbs = (self.width + 31) // 32
        out = np.zeros((limbs, count), dtype=np.uint64)      # a limb's words side by side
        for name, f in self.fields.items():
            raw = np.asarray(columns[name], dtype=np.int64).astype(np.uint64) & np.uint64(f.mask)
            lo = f.lsb
            while raw.size and lo < f.lsb + f.width:
                limb, bit = divmod(lo, 32)
                take = min(32 - bit, f.lsb + f.width - lo)
                part = (raw >> np.uint64(lo - f.lsb)) & np.uint64((1 << take) - 1)
                out[limb] |= part << np.uint64(bit)
                lo += take
        return np.ascontiguousarray(out.T, dtype=np.uint32)

    def unpack_words(self, words: np.ndarray) -> dict[str, np.ndarray]:
        """The fields (int64, signed where the field is) of an (N, limbs) uint32 array of
        :meth:`pack_words`' layout. Fields up to 63 bits."""
        wide = np.asarray(words, dtype=np.uint64)
        out = {}
        for name, f in self.fields.items():
            raw = np.zeros(len(wide), dtype=np.uint64)
            lo = f.lsb
            while lo < f.lsb + f.width:
                limb, bit = divmod(lo, 32)
                take = min(32 - bit, f.lsb + f.width - lo)
                part = (wide[:, limb] >> np.uint64(bit)) & np.uint64((1 << take) - 1)
                raw |= part << np.uint64(lo - f.lsb)
                lo += take
            value = raw.astype(np.int64)
            out[name] = value - (1 << f.width) * (value >> (f.width - 1)) if f.signed else value
        return out

    def pack_hex(self, columns: dict[str, np.ndarray]) -> list[str]:
        """Pack N items (one int array per field) to N hex lines (exactly ceil(width/4) digits)."""
        out = self.pack_words(columns)
        limbs = out.shape[1]
        digits = (self.width + 3) // 4
        text = out[:, ::-1].astype(">u4").tobytes().hex()
        step = limbs * 8
        return [text[i + step - digits:i + step] for i in range(0, len(text), step)]

    def field_slices(self) -> list[tuple[str, Field]]:
        return sorted(self.fields.items(), key=lambda kv: kv[1].lsb)


@dataclass
class PortMap:
    top: str
    ports: dict[str, Port]
    i: Stream
    o: Stream
    clk: str
    rst: str
    latency_cycles: int | None
    cycles_per_result: int | float | None   # a mean: a core of two poses a program, 560.5
    raw: dict
    path: Path | None = None

    @property
    def tag_field(self) -> str | None:
        for s in (self.o,):
            for name in s.fields:
                if name == "tag" or name.endswith("tag"):
                    return name
        return None


def _direction(spec) -> str:
    d = str(spec.get("direction", spec.get("dir", ""))).lower()
    if d in ("i", "in", "input"):
        return "input"
    if d in ("o", "out", "output"):
        return "output"
    raise ValueError(f"port direction {d!r}")


def _ports(doc) -> dict[str, Port]:
    ports = doc.get("ports")
    if isinstance(ports, dict):
        items = [(name, spec) for name, spec in ports.items()]
    elif isinstance(ports, list):
        items = [(spec["name"], spec) for spec in ports]
    else:
        raise ValueError("port map has no 'ports'")
    return {name: Port(name, _direction(spec), int(spec.get("width", 1))) for name, spec in items}


def _field(name: str, spec: dict) -> Field:
    if "bits" in spec and isinstance(spec["bits"], (list, tuple)):
        a, b = spec["bits"]
        lsb, width = min(a, b), abs(a - b) + 1
    elif "msb" in spec and "lsb" in spec:
        lsb, width = int(spec["lsb"]), int(spec["msb"]) - int(spec["lsb"]) + 1
    else:
        lsb = int(spec.get("lsb", spec.get("offset", spec.get("start", 0))))
        width = int(spec["width"])
    signed = spec.get("signed", spec.get("signedness", True))
    if isinstance(signed, str):
        signed = signed.lower() in ("signed", "true", "s")
    frac = spec.get("frac", spec.get("frac_bits"))
    return Field(name, lsb, width, bool(signed), None if frac is None else int(frac))


def _fields(spec) -> dict[str, Field]:
    if isinstance(spec, dict) and "fields" in spec:
        spec = spec["fields"]
    if isinstance(spec, dict):
        return {name: _field(name, s) for name, s in spec.items()}
    return {s["name"]: _field(s["name"], s) for s in spec}


def _find_fields(doc: dict, side: str, payload_port: str) -> dict[str, Field]:
    """Payload fields of one side, wherever the generator put them."""
    candidates = []
    for key in ("payload", "payloads", "fields"):
        node = doc.get(key)
        if isinstance(node, dict):
            candidates += [node.get(payload_port), node.get(side)]
            for alias in ({"i": ("in", "input", "inputs"), "o": ("out", "output", "outputs")}[side]):
                candidates.append(node.get(alias))
    for alias in ({"i": ("inputs", "in_fields", "input_fields"), "o": ("outputs", "out_fields", "output_fields")}[side]):
        candidates.append(doc.get(alias))
    port = doc.get("ports", {})
    if isinstance(port, dict) and isinstance(port.get(payload_port), dict):
        candidates.append(port[payload_port].get("fields"))
    elif isinstance(port, list):
        for spec in port:
            if spec.get("name") == payload_port:
                candidates.append(spec.get("fields"))
    for cand in candidates:
        if cand:
            return _fields(cand)
    raise ValueError(f"port map: no payload fields for {payload_port!r}")


def _stream(ports: dict[str, Port], side: str, direction: str) -> tuple[str, str, str]:
    """Names of (valid, ready, payload) of the stream whose payload has ``direction``."""
    def pick(suffix: str, want: str) -> str:
        names = [n for n, p in ports.items() if p.direction == want and n.lower().endswith(suffix)]
        pref = [n for n in names if n.lower().startswith(side)]
        if len(pref) == 1:
            return pref[0]
        if len(names) == 1:
            return names[0]
        raise ValueError(f"port map: cannot tell the {side} stream's {suffix} port among {names}")
    other = "output" if direction == "input" else "input"
    return pick("valid", direction), pick("ready", other), pick("payload", direction)


def load_portmap(path: str | Path | dict) -> PortMap:
    if isinstance(path, dict):
        doc, where = path, None
    else:
        where = Path(path)
        doc = json.loads(where.read_text())
    ports = _ports(doc)
    streams = doc.get("streams")
    if isinstance(streams, dict) and "i" in streams and "o" in streams:
        # The generator's own layout (hdl/generate.py, port map version 1).
        si, so = streams["i"], streams["o"]
        i = Stream(si["valid"], si["ready"], si["payload"], ports[si["payload"]].width, _fields(si["fields"]))
        o = Stream(so["valid"], so["ready"], so["payload"], ports[so["payload"]].width, _fields(so["fields"]))
    else:
        iv, ir, ip = _stream(ports, "i", "input")
        ov, orr, op = _stream(ports, "o", "output")
        i = Stream(iv, ir, ip, ports[ip].width, _find_fields(doc, "i", ip))
        o = Stream(ov, orr, op, ports[op].width, _find_fields(doc, "o", op))
    for s in (i, o):
        for name in (s.valid, s.ready, s.payload):
            if name not in ports:
                raise ValueError(f"port map: stream port {name!r} is not among the ports")
    clk = doc.get("clock") or next(n for n, p in ports.items()
                                   if p.direction == "input" and n.lower() in ("clk", "clock", "sync_clk"))
    rst = doc.get("reset") or next(n for n, p in ports.items()
                                   if p.direction == "input" and n.lower() in ("rst", "reset", "sync_rst"))
    top = doc.get("module") or doc.get("top") or doc.get("name") or doc.get("toplevel")
    lat = doc.get("latency_cycles", doc.get("timing", {}).get("latency_cycles") if isinstance(doc.get("timing"), dict) else None)
    cpr = doc.get("cycles_per_result", doc.get("timing", {}).get("cycles_per_result") if isinstance(doc.get("timing"), dict) else None)
    for s in (i, o):
        for f in s.fields.values():
            if f.lsb + f.width > s.width:
                raise ValueError(f"port map: field {f.name} [{f.lsb}+:{f.width}] outside {s.payload} ({s.width} bits)")
    return PortMap(str(top), ports, i, o, clk, rst, None if lat is None else int(lat),
                   None if cpr is None else _cycles(cpr), doc, where)


def _cycles(value) -> int | float:
    """Cycles per result: a whole number of clocks, or their mean (a two-pose compact core)."""
    value = float(value)
    return int(value) if value.is_integer() else value
