// $alu on CCU2C carry chains that start themselves, for lost.hdl.flow.synth (ALU_MAP).
//
// Yosys's lattice/arith_map_ccu2c.v feeds the adder's carry in CI to the first cell's carry input,
// and nextpnr-ecp5 then puts a whole CCU2C before every chain to drive it (make_carry_feed_in). Here
// the chain makes its carry itself, in the first half-cell, whose LUT4 is 0 (with D0 = 1): its carry
// out is its LUT2, and the cell's carry input is never read (the flow leaves it unconnected).
// * With CI and BI constant and an even width, that half-cell is bit 0's carry (LUT2 of A[0], B[0])
//   and bit 0's sum is a LUT beside the chain (gone when unused, as in a comparison): width / 2 cells.
// * Otherwise the half-cell is the carry in (LUT2 = A0 = CI) and bit i sits in half i + 1:
//   (width + 1) / 2 cells, rounded up.
// Otherwise Yosys's map: bit i's LUT4 is A ^ B ^ BI (C = BI, D = 1), its LUT2 (A) the carry it makes.
(* techmap_celltype = "$alu" *)
module _70_ccu2c_alu_self_started (A, B, CI, BI, X, Y, CO);
	parameter A_SIGNED = 0;
	parameter B_SIGNED = 0;
	parameter A_WIDTH = 1;
	parameter B_WIDTH = 1;
	parameter Y_WIDTH = 1;

	parameter _TECHMAP_CONSTMSK_CI_ = 0;
	parameter _TECHMAP_CONSTVAL_CI_ = 0;
	parameter _TECHMAP_CONSTMSK_BI_ = 0;
	parameter _TECHMAP_CONSTVAL_BI_ = 0;

	(* force_downto *)
	input [A_WIDTH-1:0] A;
	(* force_downto *)
	input [B_WIDTH-1:0] B;
	(* force_downto *)
	output [Y_WIDTH-1:0] X, Y;

	input CI, BI;
	(* force_downto *)
	output [Y_WIDTH-1:0] CO;

	wire _TECHMAP_FAIL_ = Y_WIDTH <= 4;

	(* force_downto *)
	wire [Y_WIDTH-1:0] A_buf, B_buf;
	\$pos #(.A_SIGNED(A_SIGNED), .A_WIDTH(A_WIDTH), .Y_WIDTH(Y_WIDTH)) A_conv (.A(A), .Y(A_buf));
	\$pos #(.A_SIGNED(B_SIGNED), .A_WIDTH(B_WIDTH), .Y_WIDTH(Y_WIDTH)) B_conv (.A(B), .Y(B_buf));

	// Bit 0's carry as a LUT2 of (A[0], B[0]) (INIT index {B, A}) for constant CI and BI.
	function [3:0] bit0_carry;
		input ci, bi;
		integer k;
		reg a, b;
		begin
			for (k = 0; k < 4; k = k + 1) begin
				a = k & 1;
				b = ((k >> 1) & 1) ^ bi;
				bit0_carry[k] = (a & b) | (ci & (a ^ b));
			end
		end
	endfunction

	localparam FOLD = _TECHMAP_CONSTMSK_CI_ && _TECHMAP_CONSTMSK_BI_ && (Y_WIDTH % 2 == 0);
	localparam [15:0] START = FOLD ? {12'b0, bit0_carry(_TECHMAP_CONSTVAL_CI_, _TECHMAP_CONSTVAL_BI_)} : 16'b0000000000001010;
	// Bit i sits in half i + SHIFT.
	localparam SHIFT = FOLD ? 0 : 1;
	localparam HALVES = FOLD ? Y_WIDTH : ((Y_WIDTH + 2) / 2) * 2;

	(* force_downto *)
	wire [Y_WIDTH-1:0] BB = BI ? ~B_buf : B_buf;
	(* force_downto *)
	wire [HALVES-1:0] AH, BH, BBH;
	generate if (FOLD) begin:folded
		assign AH = A_buf;
		assign BH = B_buf;
		assign BBH = BB;
	end else begin:started
		assign AH = {A_buf, CI};
		assign BH = {B_buf, 1'b0};
		assign BBH = {BB, 1'b0};
	end endgenerate

	(* force_downto *)
	wire [HALVES-1:0] FCO, SH, COH;
	// The carry into half j (j >= 1) is the carry out of half j - 1.
	(* force_downto *)
	wire [HALVES-1:0] CH = {COH[HALVES-2:0], 1'bx};
	wire bit0_carry_out = (A_buf[0] && BB[0]) || (CI && (A_buf[0] || BB[0]));

	genvar j;
	generate for (j = 0; j < HALVES; j = j + 2) begin:slice
		CCU2C #(
			.INIT0(j == 0 ? START : 16'b1001011010101010),
			.INIT1(16'b1001011010101010),
			.INJECT1_0("NO"),
			.INJECT1_1("NO")
		) ccu2c_i (
			.CIN(j == 0 ? 1'bx : FCO[j - 2]),
			.A0(AH[j]), .B0(j == 0 && !FOLD ? 1'b0 : BH[j]), .C0(j == 0 ? 1'b0 : BI), .D0(1'b1),
			.A1(AH[j+1]), .B1(BH[j+1]), .C1(BI), .D1(1'b1),
			.S0(SH[j]), .S1(SH[j+1]),
			.COUT(FCO[j])
		);

		assign COH[j] = j == 0 ? (FOLD ? bit0_carry_out : CI) : (AH[j] && BBH[j]) || (CH[j] && (AH[j] || BBH[j]));
		assign COH[j+1] = FCO[j];
	end endgenerate

	generate if (FOLD) begin:folded_outputs
		assign Y = {SH[Y_WIDTH-1:1], A_buf[0] ^ BB[0] ^ CI};
		assign CO = COH[Y_WIDTH-1:0];
	end else begin:started_outputs
		assign Y = SH[Y_WIDTH:1];
		assign CO = COH[Y_WIDTH:1];
	end endgenerate
	assign X = A_buf ^ BB;
endmodule
