// `ropsim vectors UNIT -o FILE [--format csv|hex]`: golden test vectors for
// RTL verification (docs/vectors.md, docs/rtl.md): random cases, or with
// `--trace T` the unit's calls while the golden model replays a trace.
#include <fmt/format.h>

#include <memory>

#include "sim/cli/cli_common.h"
#include "sim/driver/vectors.h"
#include "util/output_file.h"

namespace ropsim {

namespace {

struct VectorOpts {
  std::string unit, out;
  uint64_t count = 1000, seed = 1;
  Numerics num;
  VectorOptions opt;
  // --trace
  std::string trace, method = "lk", enderton_selection = "depth-first", window;
  uint32_t draw = 0;
};

/// --window x0,y0,x1,y1: four pixel coordinates, inclusive.
TraceVectorRequest::Window parse_window(const std::string& s) {
  TraceVectorRequest::Window b{};
  uint32_t* v[4] = {&b.x0, &b.y0, &b.x1, &b.y1};
  size_t at = 0;
  for (int i = 0; i < 4; ++i) {
    const size_t end = i < 3 ? s.find(',', at) : s.size();
    const std::string part = end == std::string::npos ? "" : s.substr(at, end - at);
    if (part.empty() || part.size() > 5 || part.find_first_not_of("0123456789") != std::string::npos ||
        std::stoul(part) > 65535)
      throw UserError("--window " + s + ": expected x0,y0,x1,y1 (pixels, 0..65535)");
    *v[i] = uint32_t(std::stoul(part));
    at = end + 1;
  }
  if (b.x0 > b.x1 || b.y0 > b.y1) throw UserError("--window " + s + ": x0 > x1 or y0 > y1");
  return b;
}

int trace_vectors(const VectorOpts& o, const CLI::App& sub) {
  TraceVectorRequest req;
  req.input.trace_path = o.trace;
  parse_method(o.method, req.method.method);
  parse_enderton_selection(o.enderton_selection, req.method.enderton_selection);
  req.method.numerics = o.num;
  req.method.seed = o.seed;
  req.format = o.opt.format;
  if (!o.window.empty()) req.window = parse_window(o.window);
  if (sub.count("--draw")) req.draw = o.draw;
  ensure_parent_dir(o.out);
  OutputFile::Options oo;
  oo.allow_stdout = true;
  OutputFile out(o.out, oo);
  uint64_t rows = 0;
  try {
    rows = make_trace_vectors(o.unit, req, [&out](std::string_view s) { out.write(s); });
  } catch (const VectorError& e) {
    throw UserError(std::string("vectors: ") + e.what());
  }
  out.commit();
  if (o.out != "-") fmt::print("wrote {}: {} vectors for {} from {}\n", o.out, rows, o.unit, o.trace);
  return 0;
}

int cmd_vectors(const VectorOpts& o, const CLI::App& sub) {
  if (const char* err = validate(o.num)) throw UserError(err);
  if (!o.trace.empty()) return trace_vectors(o, sub);
  for (const char* f : {"--method", "--enderton-selection", "--window", "--draw"})
    if (sub.count(f)) throw UserError(std::string(f) + " applies to vectors from a trace (--trace T)");
  std::string text;
  try {
    text = make_vectors(o.unit, o.count, o.seed, o.num, o.opt);
  } catch (const VectorError& e) {
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
  CLI::App* vec = app.add_subcommand(
      "vectors",
      "Golden test vectors (CSV or $readmemh hex) for one unit, for RTL verification: random cases, or "
      "the unit's calls while a trace replays (--trace)");
  vec->add_option("UNIT", o->unit, "Unit: " + join(vector_units()))->required()->check(CLI::IsMember(vector_units()));
  CLI::Option* count = vec->add_option("--count", o->count, "Number of random vectors (default 1000)")
                           ->check(in_range(uint64_t{1}, uint64_t{100000000}));
  vec->add_option("-o,--out,--output", o->out, "File to write (- for standard output)")->required()->type_name("FILE");
  vec->add_option("--format", o->opt.format, "csv (default) or hex: one $readmemh word per vector")
      ->check(CLI::IsMember(vector_formats()));
  CLI::Option* spp =
      vec->add_option("--spp", o->opt.spp, "Samples per pixel of every vector (default: 1..64 at random)")
          ->check(CLI::IsMember({1, 2, 4, 8, 16, 32, 64}));
  CLI::Option* order =
      vec->add_option("--order", o->opt.hilbert_order, "hilbert: log2 of the grid side (default: 1..16 at random)")
          ->check(in_range(1, 16));
  vec->add_option("--seed", o->seed,
                  "Seed of the random cases (default 1); with --trace, of the method's hash-based random numbers");
  vec->add_option("--hash-bits", o->num.hash_bits, "alpha-ref: hash width (8..32)")->check(in_range(8, 32));
  vec->add_option("--alpha-bits", o->num.alpha_bits, "opacity: opacity precision (1..32)")->check(in_range(1, 32));
  vec->add_option("--surface-id-bits", o->num.surface_id_bits, "tracker, alpha-ref: surface id width (1..32)")
      ->check(in_range(1, 32));
  vec->add_option("--trace", o->trace,
                  "Vectors from this trace: every call of the unit while the golden model replays it (units: " +
                      join(trace_vector_units()) + ")")
      ->check(CLI::ExistingFile)
      ->excludes(count)
      ->excludes(spp)
      ->excludes(order);
  vec->add_option("--method", o->method, "--trace: the method replayed (default lk)")
      ->check(CLI::IsMember(method_names()));
  vec->add_option("--enderton-selection", o->enderton_selection,
                  "--trace: enderton's selection, depth-first (default) or original")
      ->check(CLI::IsMember({"depth-first", "original"}));
  vec->add_option("--window", o->window, "--trace: only the calls for pixels x0 <= x <= x1, y0 <= y <= y1")
      ->type_name("x0,y0,x1,y1");
  vec->add_option("--draw", o->draw, "--trace: only the calls for fragments of this draw id");
  vec->footer(examples({"ropsim vectors alpha-ref --count 100 -o alpha_ref.csv",
                        "ropsim vectors alpha-ref --format hex --count 100 -o alpha_ref.hex   # $readmemh words",
                        "ropsim vectors tracker --trace cloth.trace --window 100,100,115,115 -o tracker_cloth.csv"}));
  return [o, vec]() { return vec->parsed() ? cmd_vectors(*o, *vec) : -1; };
}

}  // namespace ropsim
