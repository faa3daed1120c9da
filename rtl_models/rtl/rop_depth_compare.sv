// Depth test of LK Figure 7 line 2 (rtl_models/algo/depth.h, depth_passes):
// a covered sample survives when its depth z <= the stored depth (ties pass,
// LESS_EQUAL). Depths are canonical binary32 in [+0, 1] (canonical_depth:
// -0 and negatives are +0), so their bit patterns order like their values
// and the compare is an unsigned 31-bit magnitude compare (bit 31 is always
// 0). LANES comparators (depth_test.samples_per_clock); latency STAGES
// (depth_test.latency_cycles, after the stored depth arrives).
module rop_depth_compare #(
    parameter int LANES  = 16,
    parameter int STAGES = 2
) (
    input  logic                clk,
    input  logic                rst,
    input  logic                in_valid,
    input  logic [         LANES-1:0] covered,
    /* verilator lint_off UNUSEDSIGNAL */  // bit 31 of a canonical depth is 0
    input  logic [LANES*32-1:0] z,       // sample depths, lane j at [j*32 +: 32]
    input  logic [LANES*32-1:0] stored,  // stored depths
    /* verilator lint_on UNUSEDSIGNAL */
    output logic                out_valid,
    output logic [   LANES-1:0] pass
);
  logic [LANES-1:0] d;
  for (genvar j = 0; j < LANES; j++) begin : g_lane
    assign d[j] = covered[j] && (z[j*32+:31] <= stored[j*32+:31]);
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
