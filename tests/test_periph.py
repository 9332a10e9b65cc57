"""The IK peripheral (hdl/soc/periph.py) on its Wishbone bus, in Amaranth's simulator: poses in,
results bit-exact to the model, every access acknowledged on the next clock, and the misuse the
register map defines (ik5r.core.regmap): joints read before done, start while full, a write to a
read-only register, an unmapped offset. The register map's generated texts are checked here too.
"""

from __future__ import annotations

import json
import random
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from amaranth.sim import Simulator

from ik5r.core import regmap as R
from ik5r.core.fxconfig import constants, load_config
from ik5r.core.regmap_out import c_header, csr_json, markdown_table, svd

OFF = {r.name: r.offset // 4 for r in R.REGISTERS}
EV = {f.name: 1 << f.lsb for f in R.by_name("EVENTS").fields}


@pytest.fixture(scope="module")
def k18():
    return constants(load_config("q18"))


def test_regmap_is_consistent_and_texts_carry_every_register():
    names = [r.name for r in R.REGISTERS]
    assert len(set(names)) == len(names)
    offsets = [r.offset for r in R.REGISTERS]
    assert len(set(offsets)) == len(offsets) and max(offsets) < R.MAP_BYTES
    header = c_header()
    doc = json.loads(csr_json(0x1000))
    device = ET.fromstring(svd(0x1000))
    svd_names = [e.text for e in device.iter("register") for e in e.findall("name")]
    assert svd_names == names
    table = markdown_table()
    for r in R.REGISTERS:
        assert f"#define IK5R_REG_{r.name} 0x{r.offset:03X}u" in header
        assert doc["csr_registers"][f"ik5r_{r.name.lower()}"]["addr"] == 0x1000 + r.offset
        assert f"| 0x{r.offset:03X} | `{r.name}` | {r.access} |" in table
    with pytest.raises(ValueError, match="overlapping"):
        R.Register("X", 0, "RW", "x", (R.Field("A", 0, 4, "a"), R.Field("B", 3, 2, "b")))
    with pytest.raises(ValueError, match="bad access"):
        R.Register("X", 2, "RW", "x")


class Master:
    """A Wishbone classic master: one access at a time, random idle clocks between accesses;
    asserts that a write is acknowledged in its own clock, a read in the next, and nothing
    without a request."""

    def __init__(self, ctx, bus, rng):
        self.ctx, self.bus, self.rng = ctx, bus, rng
        self.cycle = 0

    async def _tick(self):
        await self.ctx.tick()
        self.cycle += 1

    async def access(self, word: int, data: int | None = None, sel: int = 0b1111) -> int:
        ctx, bus = self.ctx, self.bus
        for _ in range(self.rng.choice((0, 0, 1, 3))):
            await self._tick()
        ctx.set(bus.adr, word)
        ctx.set(bus.we, data is not None)
        ctx.set(bus.dat_w, 0 if data is None else data & 0xFFFF_FFFF)
        ctx.set(bus.sel, sel)
        ctx.set(bus.cyc, 1)
        ctx.set(bus.stb, 1)
        # A write is acknowledged in its request's clock, a read in the next (its data registered).
        if data is None:
            assert not ctx.get(bus.ack)
            await self._tick()
        assert ctx.get(bus.ack) and not ctx.get(bus.err)
        value = ctx.get(bus.dat_r)
        await self._tick()
        ctx.set(bus.cyc, 0)
        ctx.set(bus.stb, 0)
        assert not ctx.get(bus.ack)      # no acknowledgement without a request
        return value

    async def read(self, name_or_word) -> int:
        return await self.access(OFF.get(name_or_word, name_or_word))

    async def write(self, name_or_word, data: int, sel: int = 0b1111) -> int:
        return await self.access(OFF.get(name_or_word, name_or_word), data, sel)

    async def start(self, pose: list[int], flags: int) -> None:
        for r, word in zip(R.POSE_REGISTERS, pose):
            await self.write(r.name, word)
        await self.write("CTRL", flags | 1 << 8)

    async def result(self) -> tuple[list[int], int, int]:
        word = await self.read("RESULT")
        joints = [await self.read(f"Q{j}") for j in range(1, 6)]
        return [q - (1 << 32) if q >> 31 else q for q in joints], word & 0x3F, (word >> 8) & 0xFF


def _poses(k, count, seed):
    from ik5r.firmware_model import vector, vectors

    batch = vectors.random_poses(k, max(1, count // 8 + 1), seed)[:count]
    q, status = vector.solve_batch(k, *batch.args())
    rows = []
    for i in range(len(batch)):
        pose = [*batch.p[i], *batch.a[i], *batch.n[i], *batch.o[i], batch.q5[i]]
        flags = int(batch.roll[i]) | int(batch.back[i]) << 1 | int(batch.down[i]) << 2
        rows.append(([int(v) for v in pose], flags, [int(v) for v in q[i]], int(status[i])))
    return rows


def _run(periph, bench, limit=200_000):
    sim = Simulator(periph)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run_until(limit * 1e-8)


@pytest.fixture(scope="module")
def compact18(k18):
    from ik5r.hdl.soc.periph import IKPeripheral

    return IKPeripheral(constants=k18, core="compact")


def test_compact_results_bit_exact_and_misuse_defined(k18, compact18):
    periph = compact18
    rows = _poses(k18, 3, seed=11)
    seen = {}

    async def bench(ctx):
        m = Master(ctx, periph.bus, random.Random(3))
        ids = {name: await m.read(name) for name in ("ID", "VERSION", "CONFIG_HASH", "ARM_HASH", "CORE")}
        seen["ids"] = ids
        # Before any start: joints read 0, RESULT shows nothing, Q1 reads do not count, Q5 does.
        seen["empty"] = [await m.read(f"Q{j}") for j in range(1, 6)] + [await m.read("RESULT")]
        seen["events_empty"] = await m.read("EVENTS")
        await m.write("EVENTS", 0xFFFF_FFFF)
        # Writes to read-only registers are ignored and flagged; unmapped offsets read 0.
        await m.write("ID", 0x1234_5678)
        await m.write("Q1", 0x1)
        seen["ro"] = (await m.read("ID"), await m.read("Q1"), await m.read("EVENTS"))
        await m.write("EVENTS", EV["RO_WRITE"])
        seen["unmapped"] = (await m.read(R.END // 4), await m.write(R.MAP_BYTES // 4 - 1, 7),
                            await m.read("EVENTS"))
        await m.write("EVENTS", 0xFFFF_FFFF)
        # Byte lanes: a write of one lane changes one byte.
        await m.write("PX", 0x1122_3344)
        await m.write("PX", 0xAABB_CCDD, sel=0b0100)
        seen["lanes"] = await m.read("PX")
        # Three poses started back to back (the core holds them), then a fourth while full.
        for pose, flags, _, _ in rows:
            await m.start(pose, flags)
        await m.start(rows[0][0], rows[0][1])
        await m.start(rows[0][0], rows[0][1])
        seen["after_starts"] = await m.read("RESULT"), await m.read("EVENTS")
        await m.write("IRQ_ENABLE", 1)
        kept = (seen["after_starts"][0] >> 16) & 0xFFF
        results = []
        while len(results) < kept:
            word = await m.read("RESULT")
            if word >> 31:
                seen.setdefault("irq", ctx.get(periph.irq))
                results.append(await m.result())
        seen["results"] = results
        seen["final"] = await m.read("RESULT"), await m.read("EVENTS"), ctx.get(periph.irq)

    _run(periph, bench)
    assert seen["ids"]["ID"] == R.ID_MAGIC and seen["ids"] == periph.ids
    assert seen["ids"]["CORE"] & 3 == R.CORE_KINDS["compact"] and (seen["ids"]["CORE"] >> 8) & 63 == 18
    assert seen["empty"] == [0] * 6
    assert seen["events_empty"] == EV["EMPTY_READ"]
    assert seen["ro"] == (R.ID_MAGIC, 0, EV["RO_WRITE"])
    assert seen["unmapped"] == (0, 0, EV["UNMAPPED"])
    assert seen["lanes"] == 0x11BB_3344
    kept = (seen["after_starts"][0] >> 16) & 0xFFF
    overrun = bool(seen["after_starts"][1] & EV["OVERRUN"])
    # Five starts: those the queue had room for are kept, in order, the others dropped and flagged.
    assert 3 <= kept <= min(5, periph.capacity) and overrun == (kept < 5)
    expected = [(q, st, tag) for tag, (_, _, q, st) in enumerate(rows + [rows[0], rows[0]])]
    assert [tuple(r) for r in seen["results"]] == expected[:kept]
    assert seen["irq"] == 1
    final, events, irq = seen["final"]
    assert final == 0 and irq == 0 and events & EV["DONE"]


def test_readme_register_table_is_the_generated_one():
    from pathlib import Path

    from ik5r.tools.results import regmap_section

    text = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    assert "<!-- regmap:begin -->" in text and regmap_section(text) == text
