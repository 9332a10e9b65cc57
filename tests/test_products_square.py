"""Squares in the multipliers (``hdl/datapath/products.py``, issue 30): each cross term once,
doubled by a shift, one operand register; the same exact sum, so the same bits.

The sum of a square's terms is checked as integers over every limb split the cores use (the
terms are what the pipelined build makes partial products of), the detection of a square on the
operand functions, and the IK core's DSP count. Every bit of the cores is checked by the
simulations (``tests/test_ik_core.py``, ``tests/test_cocotb_core.py``, ``tests/test_harness.py``).
"""

from __future__ import annotations

import gc
import random

import pytest
from amaranth.hdl import signed, unsigned

from ik5r.hdl.datapath.products import SQUARE, _is_square, _partial_products


def _limb_value(x: int, width: int, lo: int, hi: int, is_signed: bool) -> int:
    raw = (x & ((1 << width) - 1)) >> lo & ((1 << (hi - lo)) - 1)
    return raw - (1 << (hi - lo)) if is_signed and raw >> (hi - lo - 1) else raw


def _sum_of_terms(terms, x: int, width: int, b_of=None) -> int:
    """The terms' sum for a = ``x`` (and b = ``b_of[1]`` in ``b_of[0]`` bits, or a square's or a
    constant's b)."""
    total = 0
    for _, shift, (a_lo, a_hi, a_signed), b_part in terms:
        if isinstance(b_part, int):
            b_limb = b_part
        elif b_of is None:
            b_limb = _limb_value(x, width, *b_part[1:])
        else:
            b_limb = _limb_value(b_of[1], b_of[0], *b_part[1:])
        total += (_limb_value(x, width, a_lo, a_hi, a_signed) * b_limb) << shift
    return total


def _words(shape, rng, count=2000):
    lo, hi = (-(1 << (shape.width - 1)), (1 << (shape.width - 1)) - 1) if shape.signed else (0, (1 << shape.width) - 1)
    values = [lo, hi, 0, 1, -1 if shape.signed else 2, lo + 1, hi - 1] + [rng.randint(lo, hi) for _ in range(count)]
    return values + [sign * (1 << k) + d for k in range(shape.width - 1) for sign in (1, -1) for d in (-1, 0, 1)
                     if lo <= sign * (1 << k) + d <= hi]


@pytest.mark.parametrize("shape", [signed(18), signed(38), unsigned(38), signed(52), unsigned(35), signed(17),
                                   signed(36), signed(53)])
def test_square_terms_sum_to_the_square(shape):
    terms = _partial_products("p", 0, shape, SQUARE)
    limbs = -(-shape.width // 17)
    # n (n + 1) / 2 limb pairs, not n * n (a narrow one may come as two halves)
    assert len({(a_range[0] // 17, b_part[1] // 17) for _, _, a_range, b_part in terms}) == limbs * (limbs + 1) // 2
    for x in _words(shape, random.Random(shape.width)):
        assert _sum_of_terms(terms, x, shape.width) == x * x, x


def _rows(a_range, b_part) -> int:
    return min(a_range[1] - a_range[0], bin(b_part).count("1") if isinstance(b_part, int) else b_part[2] - b_part[1])


@pytest.mark.parametrize("a_shape, b", [
    (signed(38), ("b", unsigned(17))), (signed(38), ("b", signed(38))), (signed(21), ("b", signed(36))),
    (unsigned(38), ("b", signed(20))), (signed(36), ("b", signed(19))), (signed(38), 0x1ABCD),
    (signed(21), 0xB), (signed(38), 0x7), (signed(52), 0x3_0000_0005), (signed(53), ("b", signed(53)))])
def test_terms_sum_to_the_product(a_shape, b):
    """Every multiplier's terms, narrow ones split in halves (``_split_narrow``), sum to the exact
    product; no term left between LUT_ROWS and NARROW_ROWS rows where the adder tree had room for
    its halves; the split never deepens the tree."""
    from ik5r.hdl.datapath.products import LUT_ROWS, NARROW_ROWS, _limb_terms, _split_narrow

    b_part = b if isinstance(b, int) else (lambda s: s, b[1])
    terms = _partial_products("p", 0, a_shape, b_part)
    unsplit = _limb_terms("p", 0, a_shape, b_part)
    assert (len(terms) - 1).bit_length() == (len(unsplit) - 1).bit_length()
    assert _split_narrow(unsplit) == terms
    middling = [t for t in terms if LUT_ROWS < _rows(t[2], t[3]) <= NARROW_ROWS]
    if middling:        # left whole only where halves would add a tree level
        assert len(terms) == len(unsplit) and ((len(terms) + len(middling) - 1).bit_length()
                                               > (len(terms) - 1).bit_length())
    else:
        assert len(terms) - len(unsplit) == sum(1 for t in unsplit if LUT_ROWS < _rows(t[2], t[3]) <= NARROW_ROWS)
    rng = random.Random(a_shape.width)
    b_shape = None if isinstance(b, int) else b[1]
    bs = [None] if b_shape is None else _words(b_shape, rng, 40)
    for x in _words(a_shape, rng, 300):
        for y in rng.sample(bs, min(len(bs), 4)):
            want = x * (b if y is None else y)
            assert _sum_of_terms(terms, x, a_shape.width, None if y is None else (b_shape.width, y)) == want, (x, y)


def test_square_detected_only_for_the_same_expression():
    word = signed(38)
    same = (lambda s: s["x"]), word
    assert _is_square(lambda s: s["x"], word, same)
    assert _is_square(lambda s: s["x"].shift_right(3), word, ((lambda s: s["x"].shift_right(3)), word))
    assert not _is_square(lambda s: s["x"], word, ((lambda s: s["y"]), word))
    assert not _is_square(lambda s: s["x"], word, ((lambda s: s["x"]), signed(37)))
    assert not _is_square(lambda s: s["x"], word, 12345)
    assert not _is_square(lambda s: s["x"].shift_right(2), word, ((lambda s: s["x"].shift_right(3)), word))


@pytest.mark.filterwarnings("ignore::amaranth.hdl.UnusedElaboratable")
@pytest.mark.slow        # converts the pipelined ECP5 q32w core (~15 CPU s) for this count alone
def test_ik_core_dsps():
    """The pipelined q32w core's ECP5 variant: 12 fewer MULT18X18D than one per partial product
    (176 since the near-axis rule of issue 31 added 30; 146 before it), less the narrow ones in
    LUTs: 85 (73 before the narrow terms of 3 or 4 rows were split in halves or, where the adder
    tree had no room, given a DSP)."""
    from ik5r.core.fxconfig import constants, load_config
    from ik5r.tools.testbench.runner import DEFAULT_TAG_WIDTH, generate_cached

    # The conversion the cocotb run of this core shares (tests/test_cocotb_core.py).
    text, _ = generate_cached("ik", "pipelined", constants(load_config("q32w")), DEFAULT_TAG_WIDTH, dsp="ecp5")
    assert text.count("MULT18X18D ") == 85


def _lut_cases():
    """(a shape, a limb range, b_part) of narrow partial products as the IK cores make them."""
    return [(signed(38), (34, 38, True), ("b", unsigned(17), (0, 17, False))),
            (unsigned(38), (0, 17, False), ("b", signed(38), (34, 38, True))),
            (signed(38), (34, 38, True), ("b", signed(38), (34, 38, True))),
            (signed(21), (17, 21, True), ("b", signed(2), (0, 2, True))),
            (unsigned(34), (17, 34, False), 5),
            (signed(21), (17, 21, True), 0x1ABCD),
            (signed(20), (17, 20, True), 3),
            # Wide: what --max-dsp puts in LUTs beyond its cap.
            (signed(34), (17, 34, True), ("b", signed(34), (17, 34, True))),
            (signed(38), (17, 34, False), 0x1ABCD),
            (unsigned(38), (17, 34, False), ("b", signed(38), (17, 34, False)))]


@pytest.mark.parametrize("case", range(10))
def test_lut_product_equals_the_product(case):
    """A narrow partial product built in LUTs (:meth:`Product.lut_value`, the pipelined ECP5
    build's shift-and-add rows) is the exact product, on the limbs' extremes and random words."""
    from amaranth.hdl import Module, Signal
    from amaranth.sim import Simulator

    from ik5r.hdl.datapath.products import NARROW_ROWS, Product

    a_shape, a_range, b = _lut_cases()[case]
    a = Signal(a_shape)
    if isinstance(b, int):
        b_signal, b_part = None, b
    else:
        b_signal = Signal(b[1])
        b_part = (b_signal,) + b[2]
    product = Product(a, a_range, b_part, shift=3)
    assert (product.rows() <= NARROW_ROWS) == (case < 7)
    exact, lut = Signal(signed(80)), Signal(signed(80))
    m = Module()
    m.d.comb += [exact.eq(product.as_value()), lut.eq(product.lut_value())]
    rng = random.Random(case)

    def words(shape):
        lo, hi = (-(1 << (shape.width - 1)), (1 << (shape.width - 1)) - 1) if shape.signed else (0, (1 << shape.width) - 1)
        return [lo, hi, 0, 1, lo + 1, hi - 1] + [rng.randint(lo, hi) for _ in range(200)]

    async def bench(ctx):
        pairs = [(x, y) for x in words(a_shape) for y in (words(b_signal.shape()) if b_signal is not None else [0])]
        for x, y in rng.sample(pairs, min(600, len(pairs))) + pairs[:36]:
            ctx.set(a, x)
            if b_signal is not None:
                ctx.set(b_signal, y)
            a_limb = _limb_value(x, a_shape.width, *a_range)
            b_limb = b if b_signal is None else _limb_value(y, b[1].width, *b[2])
            assert ctx.get(exact) == a_limb * b_limb << 3, (x, y)
            assert ctx.get(lut) == a_limb * b_limb << 3, (x, y)

    sim = Simulator(m)
    sim.add_testbench(bench)
    sim.run()


@pytest.mark.filterwarnings("ignore::amaranth.hdl.UnusedElaboratable")
def test_max_dsp_caps_the_dsp_count(tmp_path):
    """``ik5r verilog --max-dsp N``: exactly N MULT18X18D (the q18 core has more partial
    products than that), the module named for it; refused (exit 2, one line) without ECP5 DSPs."""
    import subprocess
    import sys

    def run(*extra):
        return subprocess.run([sys.executable, "-m", "ik5r", "verilog", "--block", "ik", "--arch", "pipelined",
                               "--config", "q18", "-o", str(tmp_path), *extra], capture_output=True, text=True)

    assert run("--dsp", "ecp5", "--max-dsp", "3").returncode == 0
    capped = (tmp_path / "ik5r_ik_dspecp5_max_dsp3_pipelined.v").read_text()
    assert capped.count("MULT18X18D ") == 3
    refused = run("--max-dsp", "3")
    assert refused.returncode == 2 and refused.stderr.count("\n") == 1 and "--max-dsp" in refused.stderr


class _Multiplier:
    """A pipelined stream block of one 32 x 32 signed product (:func:`add_products`), ECP5 adders
    with ``dsp_output_regs`` and every partial product in LUTs (``max_dsp=0``: no primitive, so
    Amaranth's simulator runs it): the stages the option adds, simulated."""

    @staticmethod
    def build(regs: int):
        from ik5r.core.fxconfig import constants, load_config
        from ik5r.hdl.blocks.stream_block import StreamBlock
        from ik5r.hdl.datapath.adders import adders_for
        from ik5r.hdl.datapath.products import add_products
        from ik5r.hdl.datapath.stages import Datapath

        word = signed(32)

        class Multiplier(StreamBlock):
            def __init__(self):
                dp = Datapath("mul", adders=adders_for("ecp5", regs), inputs=("a", "b"), outputs=("p",))
                self.stages = add_products(dp, "t", [(lambda s: s["a"], word, (lambda s: s["b"], word), "p")])
                super().__init__(constants=constants(load_config("q18")), arch="pipelined", tag_width=0,
                                 in_fields={"a": (word, 0, "a"), "b": (word, 0, "b")},
                                 out_fields={"p": (signed(64), 0, "a * b")}, datapath=dp, dsp="ecp5",
                                 max_dsp=0, dsp_output_regs=regs)

            def _inputs(self, payload):
                return {"a": payload.a, "b": payload.b}

            def _outputs(self, state):
                return {"p": state["p"]}

        return Multiplier()


@pytest.mark.parametrize("regs", [0, 1, 2])
def test_dsp_output_regs_add_stages_and_keep_the_product(regs):
    """``dsp_output_regs=N``: N register stages after the partial products, N cycles more
    latency, the exact product at full rate (extremes and random words)."""
    from ik5r.tools.testbench.amaranth_stream import compare, run_stream

    dut, base = _Multiplier.build(regs), _Multiplier.build(0)
    base._MustUse__used = True      # only its stages and latency are wanted
    assert dut.stages == base.stages + regs and dut.latency == base.latency + regs
    assert dut.options.get("dsp_output_regs") == (regs or None)
    rng = random.Random(regs)
    lo, hi = -(1 << 31), (1 << 31) - 1
    words = [lo, hi, 0, -1, 1] + [rng.randint(lo, hi) for _ in range(40)]
    items = [{"a": a, "b": b} for a, b in zip(words, reversed(words))]
    outputs, accepted, produced = run_stream(dut, items)
    compare(items, [{"p": item["a"] * item["b"]} for item in items], outputs)
    assert [b - a for a, b in zip(accepted, produced)] == [dut.latency] * len(items)


@pytest.mark.filterwarnings("ignore:.*created but never used")
def test_dsp_output_regs_of_the_ik_core(tmp_path):
    """The pipelined IK core's ECP5 variant with ``--dsp-output-regs``: each register a fixed
    number of cycles more (the product stages on the critical path), the module named for it;
    refused (exit 2, one line) without ECP5 DSPs, for another core or block, out of range."""
    import subprocess
    import sys

    from ik5r.core.fxconfig import constants, load_config
    from ik5r.hdl.pipelined.core import IKCore

    k = constants(load_config("q18"))
    def latency_of(**options):
        core = IKCore(constants=k, arch="pipelined", **options)
        core._MustUse__used = True      # only its latency is wanted
        return core.latency

    latency = [latency_of(dsp="ecp5", dsp_output_regs=regs) for regs in (0, 1, 2)]
    assert latency[0] == latency_of()
    assert latency[2] - latency[1] == latency[1] - latency[0] > 0
    for bad in ({"dsp_output_regs": 1}, {"dsp": "ecp5", "dsp_output_regs": 3},
                {"dsp": "ecp5", "dsp_output_regs": True}):
        with pytest.raises(ValueError, match="dsp_output_regs"):
            IKCore(constants=k, arch="pipelined", **bad)
    gc.collect()    # the refused cores are never elaborated: warn here, not in a later test

    def run(*extra):
        return subprocess.run([sys.executable, "-m", "ik5r", "verilog", "--config", "q18", "-o", str(tmp_path),
                               *extra], capture_output=True, text=True)

    done = run("--block", "ik", "--arch", "pipelined", "--dsp", "ecp5", "--dsp-output-regs", "1")
    assert done.returncode == 0, done.stderr
    assert f"latency {latency[1]} cycles" in done.stdout
    assert (tmp_path / "ik5r_ik_dspecp5_dsp_output_regs1_pipelined.v").is_file()
    for extra in (("--block", "ik", "--arch", "pipelined"), ("--block", "ik", "--arch", "compact"),
                  ("--block", "rotate", "--arch", "pipelined", "--dsp", "ecp5")):
        refused = run(*extra, "--dsp-output-regs", "1")
        assert refused.returncode == 2 and refused.stderr.count("\n") == 1, refused.stderr
        assert "--dsp-output-regs" in refused.stderr
    # ik5r sim takes it too (the variant it synthesises can be simulated): refused alike.
    refused = subprocess.run([sys.executable, "-m", "ik5r", "sim", "--block", "ik", "--config", "q18",
                              "--dsp-output-regs", "1"], capture_output=True, text=True)
    assert refused.returncode == 2 and refused.stderr.count("\n") == 1 and "--dsp-output-regs" in refused.stderr
