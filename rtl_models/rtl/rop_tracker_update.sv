// Coverage tracker update of LK 2011 section 2, Figure 7 lines 4-8 and 18
// (rtl_models/algo/tracker.h: track_surface then track_commit) for one
// fragment: if the depth-surviving samples touch a covered sample, a new
// surface starts (surface id + 1 modulo 2^SID_BITS, mask cleared);
// n = popcount(covered) after that decision is the fragment's first sequence
// index; the committed mask is covered | surviving. The per-pixel state
// (covered, surface id) is read and written by the caller (the ROP cache).
// Latency STAGES (>= 1; tracker.latency_cycles).
module rop_tracker_update #(
    parameter int SPP      = 16,  // samples per pixel, 1..64
    parameter int SID_BITS = 32,  // numerics.surface_id_bits, 1..32
    parameter int STAGES   = 1,
    localparam int NB = $clog2(SPP + 1)  // width of n (0 .. SPP)
) (
    input  logic                clk,
    input  logic                rst,
    input  logic                in_valid,
    input  logic [     SPP-1:0] covered_in,
    input  logic [SID_BITS-1:0] surface_id_in,
    input  logic [     SPP-1:0] surviving,
    output logic                out_valid,
    output logic                new_surface,
    output logic [      NB-1:0] n,
    output logic [SID_BITS-1:0] surface_id_out,
    output logic [     SPP-1:0] covered_out
);
  logic conflict;
  logic [SPP-1:0] kept;
  logic [NB-1:0] count;
  logic [SID_BITS-1:0] sid;
  assign conflict = |(surviving & covered_in);
  assign kept = conflict ? '0 : covered_in;
  assign sid = surface_id_in + {{(SID_BITS - 1) {1'b0}}, conflict};  // wraps modulo 2^SID_BITS
  always_comb begin
    count = '0;
    for (int i = 0; i < SPP; i++) count = count + {{(NB - 1) {1'b0}}, kept[i]};
  end
  rop_delay #(
      .WIDTH (1 + NB + SID_BITS + SPP),
      .STAGES(STAGES)
  ) u_pipe (
      .clk,
      .rst,
      .in_valid,
      .in_data  ({conflict, count, sid, kept | surviving}),
      .out_valid,
      .out_data ({new_surface, n, surface_id_out, covered_out})
  );
endmodule
