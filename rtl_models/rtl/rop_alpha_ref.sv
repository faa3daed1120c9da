// Alpha-reference generator: CalcAlphaRef of Laine & Karras 2011, Figure 4,
// on a HASH_BITS-wide datapath, LANES hashes per clock, STAGES pipeline
// registers. The bit-level rule is rtl_models/algo/alpha_ref.h
// (calc_alpha_refs): lane j hashes the sequence index
//   index_j = (first + j + pixel_id * SPP) mod 2^HASH_BITS
// (SPP a power of two, so the product is a shift), bit-reverses its low
// HASH_BITS bits, adds the surface id and runs four multiply-xor rounds
//   x = x ^ (x * (C_r mod 2^HASH_BITS)) mod 2^HASH_BITS.
// The result is the integer ref in [0, 2^HASH_BITS); the opacity reference is
// ref / 2^HASH_BITS.
//
// Pipeline: five steps (index + reverse + surface add, then the four rounds)
// over STAGES registers; step s sits in stage floor(s * STAGES / 5) + 1, so
// STAGES = 4 (the default design's alpha_ref.pipeline_depth) is one round
// per stage with the index formation folded into the first. STAGES > 5 adds
// pass-through stages. Inputs sampled with in_valid at cycle t appear with
// out_valid at cycle t + STAGES: the latency of the SystemC AlphaRefGen for a
// fragment of at most LANES hashes (rtl_models/units/unit_timing.h).
module rop_alpha_ref #(
    parameter int LANES      = 4,   // hashes per clock (alpha_ref.lanes)
    parameter int STAGES     = 4,   // pipeline registers (alpha_ref.pipeline_depth), >= 1
    parameter int HASH_BITS  = 32,  // hash datapath width (numerics.hash_bits), 8..32
    parameter int SPP        = 16,  // samples per pixel, a power of two 1..64
    parameter int SID_BITS   = 32,  // surface id width (numerics.surface_id_bits), 1..32
    parameter int PIXEL_BITS = 32   // pixel id (Hilbert index) width, 1..64
) (
    input  logic                       clk,
    input  logic                       rst,         // synchronous, active high: clears the valid pipeline
    input  logic                       in_valid,
    /* verilator lint_off UNUSEDSIGNAL */  // index, pixel and surface-id bits above HASH_BITS do not reach the hash
    input  logic [               31:0] first,       // sequence index of lane 0 (n + j of LK Fig. 7 line 11)
    input  logic [     PIXEL_BITS-1:0] pixel_id,
    input  logic [       SID_BITS-1:0] surface_id,
    /* verilator lint_on UNUSEDSIGNAL */
    output logic                       out_valid,
    output logic [LANES*HASH_BITS-1:0] ref_out      // lane j at [j*HASH_BITS +: HASH_BITS]
);
  localparam int H = HASH_BITS;
  localparam int W = LANES * H;
  localparam int SPP_LOG2 = $clog2(SPP);
  localparam logic [31:0] C0 = 32'h6C50B47C, C1 = 32'hB82F1E52, C2 = 32'hC7AFE638, C3 = 32'h8D22F6E6;

  // Stage of step s (0: index formation, 1..4: the rounds): s * STAGES / 5 + 1.
  localparam int ST1 = STAGES / 5 + 1, ST2 = 2 * STAGES / 5 + 1, ST3 = 3 * STAGES / 5 + 1, ST4 = 4 * STAGES / 5 + 1;

  // The round constants mod 2^HASH_BITS (kAlphaRefConstants[r] & mask).
  localparam logic [H-1:0] K0 = C0[H-1:0], K1 = C1[H-1:0], K2 = C2[H-1:0], K3 = C3[H-1:0];

  function automatic logic [H-1:0] mulxor(input logic [H-1:0] x, input logic [H-1:0] c);
    mulxor = x ^ (x * c);
  endfunction

  // Step 0, per lane: index, bit reverse, surface-id add.
  /* verilator lint_off UNUSEDSIGNAL */  // the bits of pixel_id * SPP above HASH_BITS do not reach the hash
  logic [PIXEL_BITS+SPP_LOG2-1:0] pixel_base;  // pixel_id * SPP
  /* verilator lint_on UNUSEDSIGNAL */
  logic [H-1:0] pixel_low, sid_h;
  assign pixel_base = {pixel_id, {SPP_LOG2{1'b0}}};
  if (PIXEL_BITS + SPP_LOG2 >= H) begin : g_pix_trunc
    assign pixel_low = pixel_base[H-1:0];
  end else begin : g_pix_ext
    assign pixel_low = {{(H - PIXEL_BITS - SPP_LOG2) {1'b0}}, pixel_base};
  end
  if (SID_BITS >= H) begin : g_sid_trunc
    assign sid_h = surface_id[H-1:0];
  end else begin : g_sid_ext
    assign sid_h = {{(H - SID_BITS) {1'b0}}, surface_id};
  end

  logic [W-1:0] step0;
  for (genvar j = 0; j < LANES; j++) begin : g_lane
    logic [H-1:0] index, rev;
    assign index = first[H-1:0] + j[H-1:0] + pixel_low;
    for (genvar b = 0; b < H; b++) begin : g_rev
      assign rev[b] = index[H-1-b];
    end
    assign step0[j*H+:H] = rev + sid_h;
  end

  // pipe[t]: the value held by stage t's register (pipe[0] unused).
  logic [(STAGES+1)*W-1:0] pipe;
  logic [STAGES:0] vpipe;
  assign pipe[W-1:0] = step0;
  assign vpipe[0] = in_valid;

  for (genvar t = 1; t <= STAGES; t++) begin : g_stage
    logic [W-1:0] d, q;
    logic v;
    for (genvar j = 0; j < LANES; j++) begin : g_lane
      logic [H-1:0] x0, x1, x2, x3, x4;
      assign x0 = pipe[(t-1)*W+j*H+:H];
      if (ST1 == t) begin : g_r0
        assign x1 = mulxor(x0, K0);
      end else begin : g_p0
        assign x1 = x0;
      end
      if (ST2 == t) begin : g_r1
        assign x2 = mulxor(x1, K1);
      end else begin : g_p1
        assign x2 = x1;
      end
      if (ST3 == t) begin : g_r2
        assign x3 = mulxor(x2, K2);
      end else begin : g_p2
        assign x3 = x2;
      end
      if (ST4 == t) begin : g_r3
        assign x4 = mulxor(x3, K3);
      end else begin : g_p3
        assign x4 = x3;
      end
      assign d[j*H+:H] = x4;
    end
    always_ff @(posedge clk) begin
      q <= d;
      v <= rst ? 1'b0 : vpipe[t-1];
    end
    assign pipe[t*W+:W] = q;
    assign vpipe[t] = v;
  end

  assign ref_out   = pipe[STAGES*W+:W];
  assign out_valid = vpipe[STAGES];
endmodule
