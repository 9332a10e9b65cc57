// Behavioural model of the part of the Lattice ECP5 DP16KD block RAM that ik5r instantiates
// (hdl/datapath/ecp5.py, dp16kd_delay: a stash delay line with dsp="ecp5"), for simulating that
// Verilog: 1,024 x 18 bits, port A writing only (WEA, CEA, byte enables on ADA1..ADA0, the word
// address on ADA13..ADA4), port B reading only (CEB; address on ADB13..ADB4) into its latch on
// CLKB and, with REGMODE_B = "OUTREG", through the output register (OCEB) a clock later. Chip
// selects are tied low (CSDECODE "0b000"), resets unused; port A's outputs (DOA) are left out,
// as ik5r never reads them. Yosys ships the primitive as a black
// box for synthesis; this model covers that configuration and rejects anything else at time 0.
`default_nettype none
module DP16KD #(
    parameter integer DATA_WIDTH_A = 18, parameter integer DATA_WIDTH_B = 18,
    parameter [47:0] REGMODE_A = "NOREG", parameter [47:0] REGMODE_B = "NOREG",
    parameter [39:0] RESETMODE = "SYNC", parameter [39:0] ASYNC_RESET_RELEASE = "SYNC",
    parameter [39:0] CSDECODE_A = "0b000", parameter [39:0] CSDECODE_B = "0b000",
    parameter [103:0] WRITEMODE_A = "NORMAL", parameter [103:0] WRITEMODE_B = "NORMAL",
    parameter [63:0] GSR = "DISABLED"
) (
    input wire DIA0, DIA1, DIA2, DIA3, DIA4, DIA5, DIA6, DIA7, DIA8,
    input wire DIA9, DIA10, DIA11, DIA12, DIA13, DIA14, DIA15, DIA16, DIA17,
    input wire ADA0, ADA1, ADA2, ADA3, ADA4, ADA5, ADA6, ADA7, ADA8, ADA9, ADA10, ADA11, ADA12, ADA13,
    input wire CEA, OCEA, CLKA, WEA, CSA0, CSA1, CSA2, RSTA,
    input wire DIB0, DIB1, DIB2, DIB3, DIB4, DIB5, DIB6, DIB7, DIB8,
    input wire DIB9, DIB10, DIB11, DIB12, DIB13, DIB14, DIB15, DIB16, DIB17,
    input wire ADB0, ADB1, ADB2, ADB3, ADB4, ADB5, ADB6, ADB7, ADB8, ADB9, ADB10, ADB11, ADB12, ADB13,
    input wire CEB, OCEB, CLKB, WEB, CSB0, CSB1, CSB2, RSTB,
    output wire DOB0, DOB1, DOB2, DOB3, DOB4, DOB5, DOB6, DOB7, DOB8,
    output wire DOB9, DOB10, DOB11, DOB12, DOB13, DOB14, DOB15, DOB16, DOB17
);
    localparam [47:0] OUTREG = "OUTREG", NOREG = "NOREG";
    localparam OUT_B = REGMODE_B == OUTREG;

    initial begin
        if (DATA_WIDTH_A != 18 || DATA_WIDTH_B != 18 || REGMODE_A != NOREG
                || (REGMODE_B != NOREG && !OUT_B) || CSDECODE_A != "0b000" || CSDECODE_B != "0b000"
                || RESETMODE != "SYNC" || ASYNC_RESET_RELEASE != "SYNC" || WRITEMODE_A != "NORMAL"
                || WRITEMODE_B != "NORMAL" || GSR != "DISABLED") begin
            $display("DP16KD model: unsupported configuration");
            $finish;
        end
    end

    wire [17:0] di = {DIA17, DIA16, DIA15, DIA14, DIA13, DIA12, DIA11, DIA10, DIA9,
                      DIA8, DIA7, DIA6, DIA5, DIA4, DIA3, DIA2, DIA1, DIA0};
    wire [9:0] write_addr = {ADA13, ADA12, ADA11, ADA10, ADA9, ADA8, ADA7, ADA6, ADA5, ADA4};
    wire [9:0] read_addr = {ADB13, ADB12, ADB11, ADB10, ADB9, ADB8, ADB7, ADB6, ADB5, ADB4};
    reg [17:0] mem [0:1023];
    // Power-up value 0, as the device's registers with GSR disabled.
    /* verilator lint_off PROCASSINIT */
    reg [17:0] latch = 18'd0;
    reg [17:0] out_reg = 18'd0;
    /* verilator lint_on PROCASSINIT */

    always @(posedge CLKA) begin
        if (CEA && WEA && !CSA0 && !CSA1 && !CSA2) begin
            if (ADA0) mem[write_addr][8:0] <= di[8:0];
            if (ADA1) mem[write_addr][17:9] <= di[17:9];
        end
    end

    always @(posedge CLKB) begin
        if (CEB && !CSB0 && !CSB1 && !CSB2) latch <= mem[read_addr];
        if (OCEB) out_reg <= latch;
    end

    wire [17:0] dob = OUT_B ? out_reg : latch;
    assign {DOB17, DOB16, DOB15, DOB14, DOB13, DOB12, DOB11, DOB10, DOB9,
            DOB8, DOB7, DOB6, DOB5, DOB4, DOB3, DOB2, DOB1, DOB0} = dob;

    // Unused inputs of this configuration (lint-clean).
    wire _unused = &{1'b0, OCEA, RSTA, RSTB, WEB, ADA2, ADA3, ADB0, ADB1, ADB2, ADB3,
                     DIB0, DIB1, DIB2, DIB3, DIB4, DIB5, DIB6, DIB7, DIB8, DIB9, DIB10, DIB11,
                     DIB12, DIB13, DIB14, DIB15, DIB16, DIB17};
endmodule
