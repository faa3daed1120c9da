// Sample sorter of LK 2011 section 4 / Figure 7 line 9 as a bitonic sorting
// network (Batcher 1968) of N = 2^K inputs: K (K + 1) / 2 stages of N / 2
// compare-exchange elements, one register stage each, fully pipelined (a new
// pixel every clock). The structure is rtl_models/sorter/bitonic_sorter.cpp's
// loop: merge phase p = 1..K (block size 2^p), stride 2^q for q = p-1..0;
// element (i, i + stride) for i with bit q clear, ascending when bit p of i
// is clear. Latency K (K + 1) / 2 cycles (1 for N = 1): the SystemC bitonic
// SortAlgorithm's latency_cycles.
//
// Keys are the documented sort keys of rtl_models/algo/sort_order.h,
// sort_key = stored depth bits << 6 | sample id, with one bit above them that
// is set for a sample that did not survive the depth test, so those sink to
// the end (the C++ network pads with all-ones keys instead; the survivors'
// order is the same). Keys are unique (the sample id), so the order is total.
// Output: the sample ids in sorted order and a valid bit per position (the
// first popcount(surviving) positions are valid).
module rop_bitonic_sorter #(
    parameter int N = 16  // network width: samples per pixel, a power of two 1..64
) (
    input  logic            clk,
    input  logic            rst,
    input  logic            in_valid,
    input  logic [   N-1:0] surviving,
    input  logic [N*32-1:0] stored_depth,  // sample i at [i*32 +: 32], canonical binary32
    output logic            out_valid,
    output logic [ N*6-1:0] order_id,      // position k at [k*6 +: 6]
    output logic [   N-1:0] order_valid
);
  localparam int K = $clog2(N);
  localparam int NST = K * (K + 1) / 2;  // compare-exchange stages
  localparam int PIPE = NST > 0 ? NST : 1;  // register stages
  localparam int KW = 1 + 32 + 6;  // {not surviving, depth bits, sample id}

  (* mem2reg *) logic [KW-1:0] key [(PIPE+1)*N];  // key[t*N + i]: key i after register stage t
  logic [PIPE:0] vpipe;
  for (genvar i = 0; i < N; i++) begin : g_key
    localparam logic [5:0] ID = i;
    assign key[i] = {~surviving[i], stored_depth[i*32+:32], ID};
  end
  assign vpipe[0] = in_valid;

  if (NST == 0) begin : g_single  // N = 1: nothing to sort, one register
    logic [KW-1:0] q;
    logic v;
    always_ff @(posedge clk) begin
      q <= key[0];
      v <= rst ? 1'b0 : vpipe[0];
    end
    assign key[1] = q;
    assign vpipe[1] = v;
  end else begin : g_network
    for (genvar p = 1; p <= K; p++) begin : g_phase
      for (genvar r = 0; r < p; r++) begin : g_stage
        localparam int Q = p - 1 - r;
        localparam int ST = p * (p - 1) / 2 + r;  // this stage reads key[ST * N + i], writes key[(ST + 1) * N + i]
        localparam int STRIDE = 1 << Q;
        localparam int SIZE = 1 << p;
        logic v;
        for (genvar i = 0; i < N; i++) begin : g_ce
          if ((i & STRIDE) == 0) begin : g_elem  // one compare-exchange element: (i, i + STRIDE)
            localparam int J = i + STRIDE;
            localparam bit ASCENDING = (i & SIZE) == 0;
            logic [KW-1:0] a, b, qa, qb;
            logic gt, swap;
            assign a = key[ST*N+i];
            assign b = key[ST*N+J];
            assign gt = a > b;
            assign swap = ASCENDING ? gt : !gt;  // keys are unique: !gt is a < b
            always_ff @(posedge clk) begin
              qa <= swap ? b : a;
              qb <= swap ? a : b;
            end
            assign key[(ST+1)*N+i] = qa;
            assign key[(ST+1)*N+J] = qb;
          end
        end
        always_ff @(posedge clk) v <= rst ? 1'b0 : vpipe[ST];
        assign vpipe[ST+1] = v;
      end
    end
  end

  for (genvar k = 0; k < N; k++) begin : g_out
    logic [KW-1:0] out_key;
    assign out_key = key[PIPE*N+k];
    assign order_id[k*6+:6] = out_key[5:0];
    assign order_valid[k] = !out_key[KW-1];
  end
  assign out_valid = vpipe[PIPE];
endmodule
