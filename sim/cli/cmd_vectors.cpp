// `ropsim vectors UNIT -o FILE [--format csv|hex]`: golden test vectors for
// RTL verification (docs/vectors.md, docs/rtl.md).
#include <fmt/format.h>

#include <memory>

#include "cli_common.h"
#include "vectors.h"

namespace ropsim {

namespace {

struct VectorOpts {
  std::string unit, out;
  uint64_t count = 1000, seed = 1;
  Numerics num;
  VectorOptions opt;
};

int cmd_vectors(const VectorOpts& o) {
  if (const char* err = validate(o.num)) throw UserError(err);
  std::string text;
  try {
    text = make_vectors(o.unit, o.count, o.seed, o.num, o.opt);
  } catch (const std::invalid_argument& e) {
    throw UserError(std::string("vectors: ") + e.what());
  }
  ensure_parent_dir(o.out);
  write_text_output(o.out, text, /*allow_stdout=*/true);
  if (o.out != "-") fmt::print("wrote {}: {} vectors for {}\n", o.out, o.count, o.unit);
  return 0;
}

}  // namespace

VerbRunner add_vectors_command(CLI::App& app) {
  auto o = std::make_shared<VectorOpts>();
  CLI::App* vec =
      app.add_subcommand("vectors", "Golden test vectors (CSV or $readmemh hex) for one unit, for RTL verification");
  vec->add_option("UNIT", o->unit, "Unit: " + join(vector_units()))->required()->check(CLI::IsMember(vector_units()));
  vec->add_option("--count", o->count, "Number of vectors (default 1000)")
      ->check(in_range(uint64_t{1}, uint64_t{100000000}));
  vec->add_option("-o,--out,--output", o->out, "File to write (- for standard output)")->required()->type_name("FILE");
  vec->add_option("--format", o->opt.format, "csv (default) or hex: one $readmemh word per vector")
      ->check(CLI::IsMember(vector_formats()));
  vec->add_option("--spp", o->opt.spp, "Samples per pixel of every vector (default: 1..64 at random)")
      ->check(CLI::IsMember({1, 2, 4, 8, 16, 32, 64}));
  vec->add_option("--order", o->opt.hilbert_order, "hilbert: log2 of the grid side (default: 1..16 at random)")
      ->check(in_range(1, 16));
  vec->add_option("--seed", o->seed, "Seed of the random cases (default 1)");
  vec->add_option("--hash-bits", o->num.hash_bits, "alpha-ref: hash width (8..32)")->check(in_range(8, 32));
  vec->add_option("--alpha-bits", o->num.alpha_bits, "opacity: opacity precision (1..32)")->check(in_range(1, 32));
  vec->add_option("--surface-id-bits", o->num.surface_id_bits, "tracker, alpha-ref: surface id width (1..32)")
      ->check(in_range(1, 32));
  vec->footer(examples({"ropsim vectors alpha-ref --count 100 -o alpha_ref.csv",
                        "ropsim vectors alpha-ref --format hex --count 100 -o alpha_ref.hex   # $readmemh words",
                        "ropsim vectors depth-test --spp 16 --count 100 -o depth_test.csv"}));
  return [o, vec]() { return vec->parsed() ? cmd_vectors(*o) : -1; };
}

}  // namespace ropsim
