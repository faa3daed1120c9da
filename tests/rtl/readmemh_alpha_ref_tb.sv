// Icarus Verilog check that ropsim's hex vectors are what an RTL flow reads:
// $readmemh loads `ropsim vectors alpha-ref --format hex --spp 16` (the word
// layout of docs/vectors.md), and every vector drives rop_alpha_ref (the
// default design: 32-bit hash, spp 16) with its lane-0 reference checked.
// Prints PASS or FAIL (tests/rtl/CMakeLists.txt, RTL.readmemh).
`timescale 1ns / 1ps
module readmemh_alpha_ref_tb;
  localparam int COUNT = 1000;
  localparam int STAGES = 4;
  logic [207:0] mem[0:COUNT-1];
  logic clk = 0, rst = 1, in_valid = 0;
  logic [31:0] first;
  logic [31:0] pixel_id;
  logic [31:0] surface_id;
  logic out_valid;
  logic [31:0] ref_out;
  rop_alpha_ref #(
      .LANES(1),
      .STAGES(STAGES),
      .HASH_BITS(32),
      .SPP(16),
      .SID_BITS(32),
      .PIXEL_BITS(32)
  ) dut (
      .clk,
      .rst,
      .in_valid,
      .first,
      .pixel_id,
      .surface_id,
      .out_valid,
      .ref_out
  );
  always #5 clk = ~clk;
  int errors = 0, checked = 0;
  string file;
  initial begin
    if (!$value$plusargs("VECTORS=%s", file)) begin
      $display("FAIL: no +VECTORS=FILE");
      $finish;
    end
    $readmemh(file, mem);
    @(posedge clk);
    rst <= 0;
    for (int k = 0; k < COUNT; k++) begin
      if (mem[k][175:144] != 0 || mem[k][79:72] != 16 || mem[k][71:64] != 32) begin
        $display("FAIL: vector %0d: pixel id above 32 bits, spp or hash bits not the design's", k);
        errors++;
      end else begin
        first <= mem[k][207:176];
        pixel_id <= mem[k][143:112];
        surface_id <= mem[k][111:80];
        in_valid <= 1;
        @(posedge clk);
        in_valid <= 0;
        repeat (STAGES - 1) @(posedge clk);  // the input was sampled at the first edge: out_valid after STAGES edges
        #1;
        if (!out_valid || ref_out !== mem[k][31:0]) begin
          if (errors < 5)
            $display("FAIL: vector %0d: ref %h, expected %h (out_valid %b)", k, ref_out, mem[k][31:0], out_valid);
          errors++;
        end
        checked++;
      end
    end
    if (errors == 0 && checked == COUNT) $display("PASS: %0d vectors read by $readmemh match rop_alpha_ref", checked);
    else $display("FAIL: %0d of %0d vectors differ", errors, checked);
    $finish;
  end
endmodule
