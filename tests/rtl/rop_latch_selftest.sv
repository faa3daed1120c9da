// Not part of the design: a module with a latch (q follows d while en is
// high), for RTL.synth_latch_check, which shows that scripts/synth.sh fails
// on a latch.
module rop_latch_selftest #(
    parameter int WIDTH = 4
) (
    input  logic             en,
    input  logic [WIDTH-1:0] d,
    output logic [WIDTH-1:0] q
);
  always_latch if (en) q = d;
endmodule
