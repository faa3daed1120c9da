// A STAGES-deep register pipeline for a WIDTH-bit value and its valid bit:
// the output is the input of STAGES clocks earlier (STAGES >= 1). Used by the
// single-step units (opacity test, tracker update, depth compare, Hilbert
// index) whose logic sits in front of the first register: their latency is a
// design parameter (docs/config.md), and the extra registers stand for the
// buffering a real pipeline puts there (a synthesis tool with retiming would
// spread the logic over them).
module rop_delay #(
    parameter int WIDTH  = 1,
    parameter int STAGES = 1
) (
    input  logic             clk,
    input  logic             rst,
    input  logic             in_valid,
    input  logic [WIDTH-1:0] in_data,
    output logic             out_valid,
    output logic [WIDTH-1:0] out_data
);
  logic [(STAGES+1)*WIDTH-1:0] pipe;
  logic [STAGES:0] vpipe;
  assign pipe[WIDTH-1:0] = in_data;
  assign vpipe[0] = in_valid;
  for (genvar t = 1; t <= STAGES; t++) begin : g_stage
    logic [WIDTH-1:0] q;
    logic v;
    always_ff @(posedge clk) begin
      q <= pipe[(t-1)*WIDTH+:WIDTH];
      v <= rst ? 1'b0 : vpipe[t-1];
    end
    assign pipe[t*WIDTH+:WIDTH] = q;
    assign vpipe[t] = v;
  end
  assign out_data  = pipe[STAGES*WIDTH+:WIDTH];
  assign out_valid = vpipe[STAGES];
endmodule
