// Opacity test of LK Figure 7 line 12, "s.opacity > ref", in exact integer
// arithmetic (rtl_models/algo/opacity.h, opacity_passes): the fragment's
// fixed-point opacity A in [0, 2^ALPHA_BITS] (ALPHA_BITS + 1 bits: A =
// 2^ALPHA_BITS is alpha = 1, always passes) against LANES references of
// HASH_BITS bits, A / 2^ALPHA_BITS > ref / 2^HASH_BITS, by shifting the
// narrower operand left. No rounding, no subtraction: one magnitude
// comparator of max(ALPHA_BITS + 1, HASH_BITS) bits per lane. A lane whose
// mask bit is clear reports 0. Latency STAGES (>= 1).
module rop_opacity_test #(
    parameter int LANES      = 16,  // opacity tests per clock (writeback.samples_per_clock)
    parameter int ALPHA_BITS = 32,  // numerics.alpha_bits, 8..32
    parameter int HASH_BITS  = 32,  // numerics.hash_bits, 8..32
    parameter int STAGES     = 1
) (
    input  logic                       clk,
    input  logic                       rst,
    input  logic                       in_valid,
    input  logic [       ALPHA_BITS:0] a_fixed,   // A, 0 .. 2^ALPHA_BITS
    input  logic [LANES*HASH_BITS-1:0] refs,      // lane j at [j*HASH_BITS +: HASH_BITS]
    input  logic [          LANES-1:0] mask,      // lanes holding a sample
    output logic                       out_valid,
    output logic [          LANES-1:0] pass
);
  localparam int H = HASH_BITS;
  logic [LANES-1:0] d;
  for (genvar j = 0; j < LANES; j++) begin : g_lane
    logic [H-1:0] r;
    assign r = refs[j*H+:H];
    if (ALPHA_BITS >= HASH_BITS) begin : g_shift_ref
      assign d[j] = mask[j] && (a_fixed > {1'b0, r, {(ALPHA_BITS - HASH_BITS) {1'b0}}});
    end else begin : g_shift_a
      assign d[j] = mask[j] && ({a_fixed, {(HASH_BITS - ALPHA_BITS) {1'b0}}} > {1'b0, r});
    end
  end
  rop_delay #(
      .WIDTH (LANES),
      .STAGES(STAGES)
  ) u_pipe (
      .clk,
      .rst,
      .in_valid,
      .in_data  (d),
      .out_valid,
      .out_data (pass)
  );
endmodule
