// Behavioural model of the Lattice ECP5 CCU2C (two bits of a carry chain), for simulating the
// Verilog that ik5r builds with dsp="ecp5" (hdl/expr.py, add_sub). Each half has a LUT4 of
// A, B, C, D (the propagate, INITn) and a LUT2 of A, B (the generate, INITn[3:0]); the sum is
// the propagate XOR the incoming carry, and the carry out is the incoming carry where the
// propagate is 1, else the generate. INJECT1_n = "YES" gates the incoming carry and the
// generate of that half off. The same function as the cell in Yosys's ECP5 simulation library.
`default_nettype none
module CCU2C #(
    parameter [15:0] INIT0 = 16'h0000,
    parameter [15:0] INIT1 = 16'h0000,
    parameter [23:0] INJECT1_0 = "YES",
    parameter [23:0] INJECT1_1 = "YES"
) (
    input wire CIN,
    input wire A0, B0, C0, D0, A1, B1, C1, D1,
    output wire S0, S1,
    output wire COUT
);
    localparam [23:0] YES = "YES";
    localparam INJECT_0 = INJECT1_0 == YES;
    localparam INJECT_1 = INJECT1_1 == YES;

    wire propagate_0 = INIT0[{D0, C0, B0, A0}];
    wire generate_0 = INJECT_0 ? 1'b0 : INIT0[{2'b00, B0, A0}];
    wire carry_in_0 = INJECT_0 ? 1'b0 : CIN;
    assign S0 = propagate_0 ^ carry_in_0;
    wire carry_0 = propagate_0 ? CIN : generate_0;

    wire propagate_1 = INIT1[{D1, C1, B1, A1}];
    wire generate_1 = INJECT_1 ? 1'b0 : INIT1[{2'b00, B1, A1}];
    wire carry_in_1 = INJECT_1 ? 1'b0 : carry_0;
    assign S1 = propagate_1 ^ carry_in_1;
    assign COUT = propagate_1 ? carry_0 : generate_1;
endmodule
`default_nettype wire
