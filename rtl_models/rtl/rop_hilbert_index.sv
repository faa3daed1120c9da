// Hilbert-curve pixel index (LK 2011 section 3.1; rtl_models/algo/hilbert.h,
// hilbert_xy2d): d of (x, y) on a 2^ORDER x 2^ORDER grid by the four-state
// walk of hilbert_xy2d, one level per bit pair from the top: the state
// (axes swapped, coordinates complemented) and the two coordinate bits give
// the base-4 digit and the next state. ORDER levels of a 4-input, 4-output
// table in series; latency STAGES (>= 1).
module rop_hilbert_index #(
    parameter int ORDER  = 12,  // log2 of the grid side (hilbert_side): 12 covers 4096 x 4096
    parameter int STAGES = 1
) (
    input  logic                 clk,
    input  logic                 rst,
    input  logic                 in_valid,
    input  logic [    ORDER-1:0] x,
    input  logic [    ORDER-1:0] y,
    output logic                 out_valid,
    output logic [2*ORDER-1:0] d
);
  // kStep of hilbert_xy2d: {state, bx, by} -> {digit, next state}.
  function automatic logic [3:0] step(input logic [3:0] idx);
    case (idx)
      4'd0: step = {2'd0, 2'd1};
      4'd1: step = {2'd1, 2'd0};
      4'd2: step = {2'd3, 2'd3};
      4'd3: step = {2'd2, 2'd0};
      4'd4: step = {2'd0, 2'd0};
      4'd5: step = {2'd3, 2'd2};
      4'd6: step = {2'd1, 2'd1};
      4'd7: step = {2'd2, 2'd1};
      4'd8: step = {2'd2, 2'd2};
      4'd9: step = {2'd3, 2'd1};
      4'd10: step = {2'd1, 2'd2};
      4'd11: step = {2'd0, 2'd3};
      4'd12: step = {2'd2, 2'd3};
      4'd13: step = {2'd1, 2'd3};
      4'd14: step = {2'd3, 2'd0};
      default: step = {2'd0, 2'd2};
    endcase
  endfunction

  logic [2*ORDER-1:0] digits;
  always_comb begin
    logic [1:0] state;
    logic [3:0] e;
    state = 2'd0;
    e = 4'd0;
    for (int k = ORDER - 1; k >= 0; k--) begin
      e = step({state, x[k], y[k]});
      digits[2*k+:2] = e[3:2];
      state = e[1:0];
    end
  end
  rop_delay #(
      .WIDTH (2 * ORDER),
      .STAGES(STAGES)
  ) u_pipe (
      .clk,
      .rst,
      .in_valid,
      .in_data  (digits),
      .out_valid,
      .out_data (d)
  );
endmodule
