"""The ECP5 primitives the pipelined datapaths map to with ``dsp="ecp5"`` (``ik5r.hdl.datapath.stages``):
``CCU2C`` carry chains for :func:`~ik5r.hdl.datapath.expr.add_sub` and ``MULT18X18D`` multipliers for the
partial products. Same latency, same bits as the generic operators; simulated with the models in
``hdl/sim/``.
"""

from __future__ import annotations

from amaranth.hdl import Cat, ClockSignal, Const, Instance, Signal, signed

__all__ = ["ECP5_ADD_SUB_MODULE", "CCU2C_ADD_SUB_INIT", "MULT_BITS", "BRAM_BITS", "BRAM_DEPTH", "ccu2c_add_sub", "dp16kd_delay",
           "ecp5_add_sub_verilog", "mult18x18d"]

#: Operand width of a MULT18X18D (signed).
MULT_BITS = 18

#: CCU2C LUT of one adder bit with inputs A = a, B = b, C = subtract, D = 1: the propagate LUT4
#: (D = 1 half) is A ^ B ^ C, the generate LUT2 (INIT[3:0], C = D = 0) is A. Generate A is right
#: for either sign: the carry chain reads it only when A == B ^ C, i.e. when both addends are A.
CCU2C_ADD_SUB_INIT = 0x96AA


#: The Verilog module of one :func:`~ik5r.hdl.datapath.expr.add_sub` on a CCU2C chain
#: (:func:`ecp5_add_sub_verilog`).
ECP5_ADD_SUB_MODULE = "ik5r_ccu2c_add_sub"


def ccu2c_add_sub(a_bits, b_bits, subtract, chains):
    """``a +- b`` (equal-width raw bits) as an instance of :data:`ECP5_ADD_SUB_MODULE`,
    appended to ``chains``; returns the signed sum."""
    width = len(a_bits)
    total = Signal(signed(width), name="add_sub")
    chains.append(Instance(ECP5_ADD_SUB_MODULE, p_WIDTH=width, i_A=a_bits, i_B=b_bits,
                           i_SUB=subtract, o_S=total))
    return total


def ecp5_add_sub_verilog() -> str:
    """Verilog of :data:`ECP5_ADD_SUB_MODULE`: ``S = SUB ? A - B : A + B`` (``WIDTH`` bits, A and B
    already as wide as the sum) on one chain of ECP5 ``CCU2C`` cells. :func:`~ik5r.hdl.generate.generate`
    appends it to the Verilog of a design that instantiates it.

    Position 0 of the chain turns ``SUB`` into the carry (A = C = SUB, B = 0: the propagate is 0,
    so the carry out is the generate, A); positions 1..WIDTH add a bit of A to a bit of B inverted
    when subtracting (:data:`CCU2C_ADD_SUB_INIT`). A spare top position, for a whole number of
    two-bit cells, repeats the sign bits; its sum is not used. One module for every instance
    (rather than the cells inlined in the design) keeps the Verilog small and lets Verilator
    compile the chain once per width.
    """
    init = f"16'h{CCU2C_ADD_SUB_INIT:04X}"
    return f"""
// S = SUB ? A - B : A + B on one ECP5 CCU2C carry chain whose LUTs take SUB (ik5r add_sub).
module {ECP5_ADD_SUB_MODULE} #(
    parameter WIDTH = 2
) (
    input wire [WIDTH-1:0] A,
    input wire [WIDTH-1:0] B,
    input wire SUB,
    output wire [WIDTH-1:0] S
);
    /*verilator no_inline_module*/
    localparam CELLS = (WIDTH + 2) / 2;
    wire [2*CELLS-1:0] lane_a, lane_b, lane_s;
    wire [CELLS:0] carry;
    assign carry[0] = 1'b0;
    assign lane_a[WIDTH:0] = {{A, SUB}};
    assign lane_b[WIDTH:0] = {{B, 1'b0}};
    generate
        if (2 * CELLS > WIDTH + 1) begin : spare
            assign lane_a[2*CELLS-1] = A[WIDTH-1];
            assign lane_b[2*CELLS-1] = B[WIDTH-1];
        end
    endgenerate
    genvar i;
    generate
        for (i = 0; i < CELLS; i = i + 1) begin : bit_pair
            CCU2C #(
                .INIT0({init}), .INIT1({init}), .INJECT1_0("NO"), .INJECT1_1("NO")
            ) ccu2c (
                .CIN(carry[i]),
                .A0(lane_a[2*i]), .B0(lane_b[2*i]), .C0(SUB), .D0(1'b1),
                .A1(lane_a[2*i+1]), .B1(lane_b[2*i+1]), .C1(SUB), .D1(1'b1),
                .S0(lane_s[2*i]), .S1(lane_s[2*i+1]),
                .COUT(carry[i+1])
            );
        end
    endgenerate
    assign S = lane_s[WIDTH:1];
endmodule
"""


def mult18x18d(m, name: str, a18, b18, *, enable=None, output_register: bool = True):
    """A ``MULT18X18D`` in ``m`` multiplying the signed 18-bit ``a18`` and ``b18`` into its
    input registers; returns its 36-bit product. ``enable``: the input and output registers'
    clock enable (default: always, as the pipeline); ``output_register`` False: the product
    straight from the multiplier (a clock after the operands are taken)."""
    product = Signal(signed(2 * MULT_BITS), name=f"{name}_p")
    regs = ("INPUTA", "INPUTB") + (("OUTPUT",) if output_register else ())
    registers = {f"p_REG_{reg}_{what}": value
                 for reg in regs for what, value in (("CLK", "CLK0"), ("CE", "CE0"), ("RST", "RST0"))}
    if not output_register:
        registers["p_REG_OUTPUT_CLK"] = "NONE"
    m.submodules[f"{name}_dsp"] = Instance(
        "MULT18X18D", **registers,
        p_REG_INPUTC_CLK="NONE", p_REG_PIPELINE_CLK="NONE", p_GSR="DISABLED",
        p_RESETMODE="SYNC", p_SOURCEB_MODE="B_SHIFT", p_MULT_BYPASS="DISABLED",
        **{f"i_A{bit}": a18[bit] for bit in range(MULT_BITS)},
        **{f"i_B{bit}": b18[bit] for bit in range(MULT_BITS)},
        i_SIGNEDA=Const(1, 1), i_SIGNEDB=Const(1, 1), i_SOURCEA=Const(0, 1), i_SOURCEB=Const(0, 1),
        i_CLK0=ClockSignal(), i_CE0=Const(1, 1) if enable is None else enable, i_RST0=Const(0, 1),
        **{f"o_P{bit}": product[bit] for bit in range(2 * MULT_BITS)})
    return product


#: Data bits and depth of a ``DP16KD`` in the configuration :func:`dp16kd_delay` uses.
BRAM_BITS, BRAM_DEPTH = 18, 1024


def dp16kd_delay(m, name: str, word, distance: int):
    """``word`` as it was ``distance`` clocks ago (``distance >= 4``): a ring buffer of
    ``DP16KD`` block RAMs side by side (18 bits, 1,024 deep each), written every clock through
    port A and read through port B into the RAM's own output register (``REGMODE_B="OUTREG"``:
    its clock-to-output is that of a register, where the unregistered read port's is ~5.6 ns),
    then a flip-flop. Address counters of its own step every clock, the read one
    ``distance - 3`` behind the write one (three clocks from the read address to the flip-flop)."""
    if not 4 <= distance < BRAM_DEPTH:
        raise ValueError(f"a DP16KD delay line spans 4 to {BRAM_DEPTH - 1} clocks, not {distance}")
    bits = (BRAM_DEPTH - 1).bit_length()
    write_ptr = Signal(bits, name=f"{name}_wptr")
    read_ptr = Signal(bits, name=f"{name}_rptr", init=-(distance - 3) % BRAM_DEPTH)
    m.d.sync += [write_ptr.eq(write_ptr + 1), read_ptr.eq(read_ptr + 1)]
    lanes = []
    for lane in range(-(-len(word) // BRAM_BITS)):
        data = word[lane * BRAM_BITS:(lane + 1) * BRAM_BITS]
        q = Signal(BRAM_BITS, name=f"{name}_ram{lane}_q")
        m.submodules[f"{name}_ram{lane}"] = Instance(
            "DP16KD", p_DATA_WIDTH_A=BRAM_BITS, p_DATA_WIDTH_B=BRAM_BITS, p_REGMODE_A="NOREG",
            p_REGMODE_B="OUTREG", p_RESETMODE="SYNC", p_ASYNC_RESET_RELEASE="SYNC",
            p_CSDECODE_A="0b000", p_CSDECODE_B="0b000", p_WRITEMODE_A="NORMAL", p_WRITEMODE_B="NORMAL",
            p_GSR="DISABLED",
            **{f"i_DIA{bit}": data[bit] if bit < len(data) else Const(0, 1) for bit in range(BRAM_BITS)},
            **{f"i_ADA{bit}": Const(1, 1) if bit < 2 else Const(0, 1) if bit < 4 else write_ptr[bit - 4]
               for bit in range(14)},
            i_CEA=Const(1, 1), i_OCEA=Const(0, 1), i_CLKA=ClockSignal(), i_WEA=Const(1, 1), i_RSTA=Const(0, 1),
            **{f"i_CSA{bit}": Const(0, 1) for bit in range(3)},
            **{f"i_DIB{bit}": Const(0, 1) for bit in range(BRAM_BITS)},
            **{f"i_ADB{bit}": Const(0, 1) if bit < 4 else read_ptr[bit - 4] for bit in range(14)},
            i_CEB=Const(1, 1), i_OCEB=Const(1, 1), i_CLKB=ClockSignal(), i_WEB=Const(0, 1), i_RSTB=Const(0, 1),
            **{f"i_CSB{bit}": Const(0, 1) for bit in range(3)},
            **{f"o_DOB{bit}": q[bit] for bit in range(BRAM_BITS)})
        lanes.append(q)
    out = Signal(len(word), name=f"{name}_q", reset_less=True)
    m.d.sync += out.eq(Cat(*lanes)[:len(word)])
    return out
