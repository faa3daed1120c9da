// The ropsim command line, run as a subprocess in a temporary directory:
// help, the scene -> trace workflow, one-line errors that leave no output
// behind, determinism of runs, and golden vectors.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "sim/image/heat_map.h"
#include "tests/compare_util.h"
#include "tests/vcd_reader.h"
#include "traces/format/trace.h"
#include "util/codec/image_codec.h"
#include "util/progress.h"

#ifndef ROPSIM_BINARY
#error "ROPSIM_BINARY must name the built ropsim executable (tests/CMakeLists.txt)"
#endif

namespace fs = std::filesystem;

namespace {

struct CliResult {
  int code = -1;  ///< exit status, or -1 when killed by a signal
  std::string out, err;
  std::string describe() const { return "exit " + std::to_string(code) + "\nstdout:\n" + out + "stderr:\n" + err; }
};

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::ostringstream s;
  s << f.rdbuf();
  return s.str();
}

std::vector<std::string> lines_of(const std::string& s) {
  std::vector<std::string> v;
  std::istringstream in(s);
  for (std::string l; std::getline(in, l);) v.push_back(l);
  return v;
}

/// A temporary working directory for ropsim (work/) and a separate one for the
/// captured stdout/stderr (io/), so the working directory holds only what
/// ropsim wrote. Removed afterwards.
class CliSandbox {
 public:
  CliSandbox() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    root_ = fs::temp_directory_path() /
            ("ropsim-test-cli-" + std::to_string(::getpid()) + "-" + (info ? std::string(info->name()) : "x"));
    fs::remove_all(root_);
    fs::create_directories(root_ / "work");
    fs::create_directories(root_ / "io");
  }
  ~CliSandbox() {
    std::error_code ec;
    fs::remove_all(root_, ec);
  }
  fs::path work() const { return root_ / "work"; }
  std::string path(const std::string& f) const { return (work() / f).string(); }

  /// Runs `ropsim ARGS` in work/ (args are passed through /bin/sh).
  CliResult run(const std::string& args) const {
    const fs::path out = root_ / "io" / "stdout", err = root_ / "io" / "stderr";
    const std::string cmd = "cd '" + work().string() + "' && '" ROPSIM_BINARY "' " + args + " >'" + out.string() +
                            "' 2>'" + err.string() + "' </dev/null";
    const int st = std::system(cmd.c_str());
    CliResult r;
    r.code = (st != -1 && WIFEXITED(st)) ? WEXITSTATUS(st) : -1;
    r.out = slurp(out);
    r.err = slurp(err);
    return r;
  }

  std::set<std::string> files() const {
    std::set<std::string> s;
    for (const auto& e : fs::recursive_directory_iterator(work())) s.insert(fs::relative(e.path(), work()).string());
    return s;
  }

 private:
  fs::path root_;
};

/// ropsim ARGS must fail with exactly one stderr line "ropsim: error: ..."
/// containing every needle, and create no file in the working directory.
void expect_cli_error(const CliSandbox& box, const std::string& args, const std::vector<std::string>& needles) {
  SCOPED_TRACE("ropsim " + args);
  const auto before = box.files();
  const CliResult r = box.run(args);
  EXPECT_NE(r.code, 0) << "a bad input must give a non-zero exit\n" << r.describe();
  EXPECT_NE(r.code, -1) << "ropsim crashed\n" << r.describe();
  const auto lines = lines_of(r.err);
  EXPECT_EQ(lines.size(), 1u) << "stderr must be exactly one line\n" << r.describe();
  EXPECT_FALSE(r.err.empty() || r.err.back() != '\n') << "stderr must end with a newline\n" << r.describe();
  if (!lines.empty()) {
    EXPECT_EQ(lines[0].rfind("ropsim: error: ", 0), 0u) << "stderr must start with \"ropsim: error: \"\n"
                                                        << r.describe();
    for (const auto& n : needles)
      EXPECT_NE(lines[0].find(n), std::string::npos) << "the error does not mention \"" << n << "\"\n" << r.describe();
  }
  const auto after = box.files();
  for (const auto& f : after)
    EXPECT_TRUE(before.count(f)) << "a failed command left the file " << f << " behind\n" << r.describe();
}

void expect_ok(const CliResult& r, const std::string& what) {
  EXPECT_EQ(r.code, 0) << what << " failed\n" << r.describe();
  EXPECT_TRUE(r.err.empty()) << what << " wrote to stderr\n" << r.describe();
}

/// The message TraceReader gives for a file (in-process), "" when it is valid.
std::string reader_error(const std::string& path) {
  try {
    ropsim::TraceReader r(path);
    ropsim::Fragment f;
    while (r.next(f)) {
    }
  } catch (const ropsim::TraceError& e) {
    return e.what();
  }
  return "";
}

std::string record_of(const std::string& msg) {
  const auto p = msg.find("record ");
  if (p == std::string::npos) return "";
  const auto e = msg.find(':', p);
  return msg.substr(p, e - p);
}

// ------------------------------------------------------------------ tests

TEST(Cli, EverySubcommandHasHelp) {
  CliSandbox box;
  for (const char* sub :
       {"", "run", "compare", "scene", "trace", "trace info", "trace validate", "trace dump", "vectors"}) {
    const CliResult r = box.run(std::string(sub) + " --help");
    EXPECT_EQ(r.code, 0) << "ropsim " << sub << " --help\n" << r.describe();
    EXPECT_NE(r.out.find("Usage"), std::string::npos) << "ropsim " << sub << " --help prints no usage\n"
                                                      << r.describe();
    EXPECT_TRUE(r.err.empty()) << "ropsim " << sub << " --help\n" << r.describe();
  }
  EXPECT_TRUE(box.files().empty()) << "--help wrote files";
}

TEST(Cli, SceneThenTraceValidateInfoDumpAndRun) {
  CliSandbox box;
  CliResult r = box.run("scene cloth --spp 4 -o cloth4.trace");
  expect_ok(r, "scene cloth --spp 4 -o cloth4.trace");
  ASSERT_TRUE(fs::exists(box.path("cloth4.trace"))) << r.describe();
  for (const auto& f : box.files())  // the writer's temporary files are .NAME.XXXXXX
    EXPECT_NE(f[0], '.') << "temporary file " << f << " left behind";
  // "wrote cloth4.trace: T triangles, N fragments, S covered samples"
  const auto p = r.out.find(" triangles, ");
  ASSERT_NE(p, std::string::npos) << r.describe();
  const std::string n_frags = r.out.substr(p + 12, r.out.find(' ', p + 12) - (p + 12));

  r = box.run("trace validate cloth4.trace");
  expect_ok(r, "trace validate");
  // The default trace is checksummed (docs/trace-format.md 2.3): validate names the blocks it verified.
  EXPECT_EQ(r.out.rfind("cloth4.trace: valid, " + n_frags + " fragments, ", 0), 0u) << r.describe();
  EXPECT_NE(r.out.find(" checksummed blocks verified\n"), std::string::npos) << r.describe();
  expect_ok(box.run("scene cloth --spp 4 --no-checksum -o plain4.trace"), "scene --no-checksum");
  r = box.run("trace validate plain4.trace");
  expect_ok(r, "trace validate (no checksum)");
  EXPECT_EQ(r.out, "plain4.trace: valid, " + n_frags + " fragments (no checksum)\n") << r.describe();
  fs::remove(box.path("plain4.trace"));

  r = box.run("trace info cloth4.trace");
  expect_ok(r, "trace info");
  for (const std::string& s :
       {std::string("scene cloth"), std::string("256x256"), std::string("4 spp"), std::string("depth plane"),
        std::string("compression zstd"), std::string("checksum xxh3-64, "), "fragments " + n_frags + " "})
    EXPECT_NE(r.out.find(s), std::string::npos) << "trace info lacks \"" << s << "\"\n" << r.describe();

  r = box.run("trace dump cloth4.trace --limit 3");
  expect_ok(r, "trace dump --limit 3");
  const auto lines = lines_of(r.out);
  ASSERT_EQ(lines.size(), 4u) << "a header line and 3 fragment lines expected\n" << r.describe();
  std::vector<nlohmann::json> js;
  for (const auto& l : lines) {
    try {
      js.push_back(nlohmann::json::parse(l));
    } catch (const std::exception& e) {
      FAIL() << "not a JSON line: " << l << "\n" << e.what();
    }
  }
  EXPECT_EQ(js[0].value("format", ""), "ropsim-trace") << lines[0];
  EXPECT_EQ(js[0].value("version", 0), 1) << lines[0];
  EXPECT_EQ(js[0].value("spp", 0), 4) << lines[0];
  EXPECT_EQ(js[0].value("width", 0), 256) << lines[0];
  EXPECT_EQ(js[0].value("scene", ""), "cloth") << lines[0];
  EXPECT_EQ(js[0].value("checksummed", false), true) << lines[0];
  ASSERT_TRUE(js[0].contains("sample_positions_256ths")) << lines[0];
  EXPECT_EQ(js[0]["sample_positions_256ths"].size(), 4u) << lines[0];
  // The fragments are the trace's first three, as the library reads them.
  ropsim::TraceReader reader(box.path("cloth4.trace"));
  for (int i = 0; i < 3; ++i) {
    const auto& j = js[size_t(i) + 1];
    ropsim::Fragment f;
    ASSERT_TRUE(reader.next(f));
    EXPECT_EQ(j.value("record", -1), i) << lines[size_t(i) + 1];
    EXPECT_EQ(j.value("x", -1), int(f.x)) << lines[size_t(i) + 1];
    EXPECT_EQ(j.value("y", -1), int(f.y)) << lines[size_t(i) + 1];
    EXPECT_EQ(j.value("alpha", -1.0), double(f.alpha)) << lines[size_t(i) + 1];
    for (const char* k : {"draw", "prim", "coverage", "z0", "dzdx", "dzdy", "sample_depth", "rgb"})
      EXPECT_TRUE(j.contains(k)) << "dump line lacks \"" << k << "\": " << lines[size_t(i) + 1];
    EXPECT_EQ(j["sample_depth"].size(), size_t(__builtin_popcountll(f.coverage))) << lines[size_t(i) + 1];
  }

  r = box.run("run --trace cloth4.trace --out o.png --report r.json --quiet");
  expect_ok(r, "run --trace");
  EXPECT_TRUE(r.out.empty()) << "--quiet printed\n" << r.describe();
  EXPECT_TRUE(fs::exists(box.path("o.png")));
  const auto report = nlohmann::json::parse(slurp(box.path("r.json")));
  EXPECT_EQ(report["input"].value("trace", ""), "cloth4.trace");
  EXPECT_EQ(std::to_string(report["counters"].value("fragments", uint64_t{0})), n_frags);
}

TEST(Cli, BadInputsFailInOneLineAndLeaveNoOutput) {
  CliSandbox box;
  // A truncated uncompressed trace, and a compressed one missing its last byte.
  // (Without checksums, so the reader names the cut record; a checksummed trace names the block.)
  expect_ok(box.run("scene cloth --spp 4 --compression none --no-checksum -o full.trace"), "scene --compression none");
  expect_ok(box.run("scene cloth --spp 4 --compression none -o fullck.trace"), "scene --compression none");
  expect_ok(box.run("scene enderton-1 --spp 4 -o z.trace"), "scene enderton-1");
  {
    // Cut in half, a trace whose header records its count is refused at
    // open (half the payload cannot hold it); with the count zeroed (not
    // recorded, as a writer into a pipe leaves it) the reader reaches the cut
    // and names its record or block. The checked trace's header check covers
    // the count: it is zeroed in the unchecked layout (flags 1, no check).
    const std::string full = slurp(box.path("full.trace"));
    std::ofstream(box.path("counted.trace"), std::ios::binary) << full.substr(0, full.size() / 2 + 3);
    const std::string unrecorded = full.substr(0, 42) + std::string(6, '\0') + full.substr(48);
    std::ofstream(box.path("truncated.trace"), std::ios::binary) << unrecorded.substr(0, unrecorded.size() / 2 + 3);
    const std::string fullck = slurp(box.path("fullck.trace"));
    ASSERT_EQ(fullck[10], 3) << "checksummed and checked";
    const size_t ck_head = 48 + 2 * 4 + size_t(uint8_t(fullck[40]));  // 4 spp, the scene name's length
    std::string oldck = fullck.substr(0, 10) + std::string("\x01\0", 2) + fullck.substr(12, 30) + std::string(6, '\0') +
                        fullck.substr(48, ck_head - 48) + fullck.substr(ck_head + 8);
    std::ofstream(box.path("truncatedck.trace"), std::ios::binary) << oldck.substr(0, oldck.size() / 2 + 3);
    fs::remove(box.path("fullck.trace"));
    const std::string z = slurp(box.path("z.trace"));
    std::ofstream(box.path("zcut.trace"), std::ios::binary) << z.substr(0, z.size() - 1);
    fs::remove(box.path("full.trace"));
    fs::remove(box.path("z.trace"));
  }
  const std::string trunc_err = reader_error(box.path("truncated.trace"));
  const std::string trunc_rec = record_of(trunc_err);
  ASSERT_FALSE(trunc_rec.empty()) << "the library does not name a record for the truncated trace: " << trunc_err;
  const std::string zcut_rec = record_of(reader_error(box.path("zcut.trace")));
  ASSERT_FALSE(zcut_rec.empty()) << "the library accepts a compressed trace missing its last byte";

  const std::string outs = " --out o.png --out o.exr --report r.json";
  expect_cli_error(box, "run --trace counted.trace" + outs, {"counted.trace: header: ", "bytes 42..47", "truncated"});
  expect_cli_error(box, "run --trace truncated.trace" + outs, {"truncated.trace", trunc_rec + ":"});
  expect_cli_error(box, "run --trace zcut.trace" + outs, {"zcut.trace", zcut_rec + ":"});
  expect_cli_error(box, "trace validate truncated.trace", {"truncated.trace", trunc_rec + ":"});
  expect_cli_error(box, "trace validate truncatedck.trace", {"truncatedck.trace: block ", "runs past the end"});
  expect_cli_error(box, "run --trace truncatedck.trace" + outs, {"truncatedck.trace: block ", "runs past the end"});
  expect_cli_error(box, "trace info zcut.trace", {"zcut.trace", zcut_rec + ":"});
  expect_cli_error(box, "run --trace nonexistent.trace" + outs, {"nonexistent.trace"});
  expect_cli_error(box, "trace info nonexistent.trace", {"nonexistent.trace"});
  expect_cli_error(box, "run --scene enderton-1 --method bogus" + outs, {"--method", "bogus"});
  expect_cli_error(box, "run --scene bogus" + outs, {"--scene", "bogus"});
  expect_cli_error(box, "run --scene enderton-1 --spp 3" + outs, {"--spp", "3"});
  expect_cli_error(box, "run --scene enderton-1 --spp 0" + outs, {"--spp", "0"});
  expect_cli_error(box, "run --scene enderton-1 --hash-bits 40" + outs, {"--hash-bits", "40"});
  expect_cli_error(box, "run --scene enderton-1 --method slab --slab-layers 17" + outs, {"--slab-layers", "17"});
  expect_cli_error(box, "run --scene enderton-1 --method slab --slab-bits 0" + outs, {"--slab-bits", "0"});
  expect_cli_error(box, "run --scene enderton-1 --out x.jpg --report r.json", {"x.jpg"});
  expect_cli_error(box, "run --scene enderton-1 --out ok.png --out x.jpg --report r.json", {"x.jpg"});
  expect_cli_error(box, "scene bogus -o b.trace", {"bogus"});
  expect_cli_error(box, "scene cloth --spp 3 -o b.trace", {"--spp", "3"});
  expect_cli_error(box, "vectors bogus-unit -o v.csv", {"bogus-unit"});
  expect_cli_error(box, "vectors alpha-ref --hash-bits 40 -o v.csv", {"--hash-bits"});
  expect_cli_error(box, "", {});
  expect_cli_error(box, "trace", {});

  // compare: two images of different sizes.
  expect_ok(box.run("run --scene enderton-1 --spp 1 --out small.png --quiet"), "run enderton-1");
  expect_ok(box.run("run --scene testcard --spp 1 --out big.png --quiet"), "run testcard");
  expect_cli_error(box, "compare small.png big.png", {"size"});
  expect_cli_error(box, "compare small.png missing.png", {"missing.png"});
  const CliResult same = box.run("compare small.png small.png --json");
  expect_ok(same, "compare an image with itself");
  const auto sj = nlohmann::json::parse(same.out);
  EXPECT_EQ(sj.value("rmse_8bit", -1.0), 0.0) << same.describe();
  EXPECT_TRUE(sj["psnr_db"].is_null()) << "identical images: PSNR is infinite, JSON null (was 999)\n"
                                       << same.describe();
  const CliResult same_text = box.run("compare small.png small.png");
  expect_ok(same_text, "compare an image with itself (text)");
  EXPECT_NE(same_text.out.find("PSNR inf dB"), std::string::npos) << same_text.describe();
}

// compare converts an sRGB PNG to linear light before comparing: a PNG of
// an image against the reference's EXR gives the EXR-against-EXR RMSE, up to
// 8-bit quantisation (half a code step of sRGB is at most 0.5 * 12.92 / 255
// ... in linear terms below 1/255 over the range, i.e. < 1 8-bit unit; the
// test allows 0.5 units of difference in RMSE). Before, the PNG's sRGB code
// values were compared with linear values (RMSE 44.8 where 3.73 was right).
TEST(Cli, ComparePngAgainstExrIsInLinearLight) {
  CliSandbox box;
  expect_ok(box.run("run --scene enderton-1 --spp 16 --method lk --out lk.png --out lk.exr --quiet"), "lk");
  expect_ok(box.run("run --scene enderton-1 --spp 16 --method reference --out ref.exr --quiet"), "reference");
  const CliResult ee = box.run("compare lk.exr ref.exr --json");
  const CliResult pe = box.run("compare lk.png ref.exr --json");
  expect_ok(ee, "compare EXR against EXR");
  expect_ok(pe, "compare PNG against EXR");
  const auto je = nlohmann::json::parse(ee.out), jp = nlohmann::json::parse(pe.out);
  const double exr = je.value("rmse_8bit", -1.0), png = jp.value("rmse_8bit", -1.0);
  ASSERT_GT(exr, 0.5) << "lk differs from the reference on enderton-1; the test needs a nonzero RMSE";
  EXPECT_NEAR(png, exr, 0.5) << "PNG (sRGB) against EXR (linear) must be compared in one colour space";
  EXPECT_EQ(jp.value("a_transfer", ""), "sRGB") << pe.describe();
  EXPECT_EQ(jp.value("b_transfer", ""), "linear") << pe.describe();
  EXPECT_EQ(jp.value("compared_in", ""), "linear") << pe.describe();
  // The text form says which file was converted.
  const CliResult text = box.run("compare lk.png ref.exr");
  EXPECT_NE(text.out.find("lk.png converted from sRGB"), std::string::npos) << text.describe();
}

// Progress (util/progress.h): on a terminal by default, never in a log
// unless --progress forces it, never with --quiet; every long phase has one
// (the functional model, the reference pre-pass, the cycle model, the
// live-points, the sampled units, the approximate model).
TEST(Cli, ProgressGoesToLogsOnlyWithTheFlag) {
  CliSandbox box;
  const CliResult plain = box.run("run --scene eight-layers --spp 4 --quiet --out a.exr");
  expect_ok(plain, "run without --progress");
  EXPECT_TRUE(plain.err.empty()) << "stderr is not a terminal: no progress without --progress\n" << plain.describe();
  const CliResult quiet = box.run("run --scene eight-layers --spp 4 --quiet --progress --out b.exr");
  expect_ok(quiet, "run --quiet --progress");
  EXPECT_TRUE(quiet.err.empty()) << "--quiet wins over --progress\n" << quiet.describe();
  const struct {
    const char* args;
    std::vector<const char*> lines;
  } cases[] = {
      {"run --scene eight-layers --spp 4 --progress --vs-reference --out c.exr", {"functional: 100.0 %"}},
      {"run --scene eight-layers --spp 4 --progress --fidelity cycle --vs-reference --out d.exr",
       {"reference: 100.0 %", "cycle model: 100.0 %"}},
      {"run --scene eight-layers --spp 4 --progress --fidelity approximate --out e.exr", {"approximate: 100.0 %"}},
      {"run --scene cloth --spp 4 --width 1024 --height 1024 --progress --fidelity sampled -j 2 --out f.exr",
       {"live-points: counting the input: 100.0 %", "live-points: recording: 100.0 %", "sampled: units: 100.0 %"}},
  };
  for (const auto& c : cases) {
    const CliResult r = box.run(c.args);
    EXPECT_EQ(r.code, 0) << r.describe();
    for (const char* l : c.lines)
      EXPECT_NE(r.err.find(l), std::string::npos) << c.args << ": no '" << l << "'\n" << r.describe();
  }
}

// --per-draw, --draw-csv and --maps (RunBreakdown): every draw's counters,
// in the report and the CSV, add up to the run's counters, and each per-pixel
// map (EXR) sums to its counter; the error map's RMS is the report's RMSE;
// the PNGs carry the legend below the image. Threads do not change them.
TEST(Cli, PerDrawStatisticsAndMapsAddUpToTheCounters) {
  CliSandbox box;
  for (const char* method : {"lk", "enderton", "lk+depth+ac"}) {
    SCOPED_TRACE(method);
    const std::string m = method;
    const std::string args = "run --scene smoke --spp 8 --method " + m + " --per-draw --draw-csv d-" + m +
                             ".csv --maps maps-" + m + " --vs-reference --quiet --report r-" + m + ".json";
    expect_ok(box.run(args), args);
    const auto j = nlohmann::json::parse(slurp(box.path("r-" + m + ".json")));
    const auto& draws = j["draws"];
    ASSERT_GT(draws.size(), 10u) << "smoke has 96 draws";
    std::map<std::string, uint64_t> sums;
    for (const auto& d : draws)
      for (const auto& [k, v] : d["counters"].items()) sums[k] += v.get<uint64_t>();
    for (const auto& [k, v] : j["counters"].items())
      EXPECT_EQ(sums[k], v.get<uint64_t>()) << "draws[].counters." << k << " do not add up to counters." << k;
    // The CSV: one row per draw, the same numbers.
    const auto rows = lines_of(slurp(box.path("d-" + m + ".csv")));
    ASSERT_EQ(rows.size(), draws.size() + 1) << "a header and one row per draw";
    EXPECT_EQ(rows[0].rfind("draw,fragments,samples_tested,", 0), 0u) << rows[0];
    EXPECT_EQ(rows[1].substr(0, rows[1].find(',', rows[1].find(',') + 1)),
              std::to_string(draws[0]["draw"].get<uint64_t>()) + "," +
                  std::to_string(draws[0]["counters"]["fragments"].get<uint64_t>()));
    // Each map sums to its counter.
    for (const char* map :
         {"fragments", "samples_tested", "samples_depth_passed", "samples_written", "surface_id_changes"}) {
      const ropsim::DecodedImage e = ropsim::decode_image_file(box.path("maps-" + m + "/" + map + ".exr"));
      double sum = 0;
      for (size_t i = 0; i < e.px.size(); i += size_t(e.channels)) sum += e.px[i];
      EXPECT_EQ(uint64_t(sum), j["counters"][map].get<uint64_t>()) << map << ".exr does not sum to counters." << map;
      const ropsim::DecodedImage p = ropsim::decode_image_file(box.path("maps-" + m + "/" + map + ".png"));
      EXPECT_EQ(p.height, e.height + int(ropsim::kLegendRows)) << map << ".png lacks its legend";
    }
    const ropsim::DecodedImage err = ropsim::decode_image_file(box.path("maps-" + m + "/error.exr"));
    double sq = 0;
    for (size_t i = 0; i < err.px.size(); i += size_t(err.channels)) sq += double(err.px[i]) * err.px[i];
    EXPECT_NEAR(std::sqrt(sq / double(err.width * err.height)), j["vs_reference"]["rmse_8bit"].get<double>(), 1e-3)
        << "the error map's RMS is the report's RMSE";
  }
  // The same per-draw table on one thread.
  expect_ok(box.run("run --scene smoke --spp 8 --method lk --draw-csv d1.csv --threads 1 --quiet --out x.exr"),
            "1 thr");
  EXPECT_EQ(slurp(box.path("d1.csv")), slurp(box.path("d-lk.csv"))) << "the per-draw table depends on --threads";
  expect_cli_error(box, "run --scene smoke --method reference --per-draw --out y.exr", {"--per-draw"});
}

// The cycle model's breakdown: each draw's counters are the functional
// run's (each stage's delta travels with the token), and the cycles
// attributed to the draws (retirement to retirement, in cycle order) add up
// to timing.pipeline_cycles, on one pass and on three.
TEST(CliCycle, PerDrawCountersAreTheFunctionalOnesAndCyclesAddUp) {
  CliSandbox box;
  for (const char* method : {"lk", "lk+depth+ac"}) {
    SCOPED_TRACE(method);
    const std::string m = method;
    expect_ok(box.run("run --scene smoke --spp 8 --method " + m + " --draw-csv f-" + m + ".csv --quiet --out f.exr"),
              "functional");
    expect_ok(box.run("run --fidelity cycle --scene smoke --spp 8 --method " + m + " --per-draw --draw-csv c-" + m +
                      ".csv --maps maps-" + m + " --quiet --out c.exr --report c-" + m + ".json"),
              "cycle");
    const auto f = lines_of(slurp(box.path("f-" + m + ".csv"))), c = lines_of(slurp(box.path("c-" + m + ".csv")));
    ASSERT_EQ(f.size(), c.size());
    ASSERT_EQ(c[0].rfind("draw,cycles,fragments,", 0), 0u) << c[0];
    const auto j = nlohmann::ordered_json::parse(slurp(box.path("c-" + m + ".json")));  // the report's key order
    // The cycle table ends with the DRAM bytes per buffer the report lists, read then written.
    std::string dram_cols;
    for (const char* dir : {"read", "written"})
      for (const auto& [buf, v] : j["timing"]["dram"].items())
        if (v.is_object()) dram_cols += std::string(",dram_bytes_") + dir + "." + buf;
    ASSERT_GE(c[0].size(), dram_cols.size());
    EXPECT_EQ(c[0].substr(c[0].size() - dram_cols.size()), dram_cols) << c[0];
    const size_t n_dram = size_t(std::count(dram_cols.begin(), dram_cols.end(), ','));
    for (size_t i = 0; i < f.size(); ++i) {
      // Drop the cycle table's `cycles` column and its DRAM columns.
      const size_t a = c[i].find(','), b = c[i].find(',', a + 1);
      std::string row = c[i].substr(0, a) + c[i].substr(b);
      for (size_t k = 0; k < n_dram; ++k) row.erase(row.rfind(','));
      EXPECT_EQ(row, f[i]) << "draw row " << i << " differs from the functional run's";
    }
    uint64_t cycles = 0;
    for (const auto& d : j["draws"]) cycles += d["cycles"].get<uint64_t>();
    EXPECT_EQ(cycles, j["timing"]["pipeline_cycles"].get<uint64_t>()) << "the draws' cycles do not add up";
    // Each buffer's DRAM bytes over the draws are the run's (attribution.h).
    for (const auto& [buf, v] : j["timing"]["dram"].items()) {
      if (!v.is_object()) continue;
      for (const char* k : {"bytes_read", "bytes_written"}) {
        uint64_t sum = 0;
        for (const auto& d : j["draws"]) sum += d["dram"][buf][k].get<uint64_t>();
        EXPECT_EQ(sum, v[k].get<uint64_t>()) << "draws' DRAM " << buf << "." << k;
      }
    }
    // The per-tile maps: one EXR pixel per distributor tile, each map adding
    // up to its report figure.
    const auto& t = j["timing"];
    std::map<std::string, uint64_t> want = {{"tile_cycles", t["pipeline_cycles"].get<uint64_t>()},
                                            {"tile_cache_misses", t["cache"]["misses"].get<uint64_t>()}};
    for (const char* a : {"busy", "input_starved", "output_blocked", "pixel_hazard", "memory"}) {
      uint64_t sum = 0;
      for (const auto& u : t["units"]) sum += u["cycles"][a].get<uint64_t>();
      want[std::string("tile_") + a] = sum;
    }
    const uint32_t tp = j["hardware"]["resolved"]["distributor"]["tile_pixels"].get<uint32_t>();
    for (const auto& [map, total] : want) {
      const ropsim::DecodedImage e = ropsim::decode_image_file(box.path("maps-" + m + "/" + map + ".exr"));
      EXPECT_EQ(uint32_t(e.width), (j["input"]["width"].get<uint32_t>() + tp - 1) / tp) << map;
      EXPECT_EQ(uint32_t(e.height), (j["input"]["height"].get<uint32_t>() + tp - 1) / tp) << map;
      double sum = 0;
      for (size_t i = 0; i < e.px.size(); i += size_t(e.channels)) sum += e.px[i];
      EXPECT_EQ(uint64_t(sum), total) << map << " does not add up to its report figure";
      const ropsim::DecodedImage p = ropsim::decode_image_file(box.path("maps-" + m + "/" + map + ".png"));
      EXPECT_EQ(uint32_t(p.width), j["input"]["width"].get<uint32_t>()) << map << ".png covers the screen";
    }
    EXPECT_GT(want["tile_memory"] + want["tile_pixel_hazard"], 0u) << "the test needs stalls";
    const ropsim::DecodedImage e = ropsim::decode_image_file(box.path("maps-" + m + "/samples_written.exr"));
    double sum = 0;
    for (size_t i = 0; i < e.px.size(); i += size_t(e.channels)) sum += e.px[i];
    EXPECT_EQ(uint64_t(sum), j["counters"]["samples_written"].get<uint64_t>());
  }
}

// The progress line: the share consumed, the count, the rate, the elapsed
// time, and the ETA = elapsed * (1 - f) / f once 1 % or a second is behind.
TEST(ProgressLine, ShareRateElapsedAndEta) {
  using ropsim::Progress;
  EXPECT_EQ(Progress::line("functional", "fragments", 0.25, 2'000'000, 10.0),
            "functional:  25.0 %, 2000000 fragments (200.0 k/s), 10.0 s, ETA 30.0 s");
  EXPECT_EQ(Progress::line("cycle model", "fragments", 0.5, 40'000'000, 100.0),
            "cycle model:  50.0 %, 40.0 M fragments (400.0 k/s), 1 min 40 s, ETA 1 min 40 s");
  EXPECT_EQ(Progress::line("x", "units", 0.005, 1, 0.5), "x:   0.5 %, 1 units (2.0 /s), 0.5 s")
      << "no ETA before 1 % or a second";
  EXPECT_EQ(Progress::line("x", "units", -1.0, 3'000'000, 1.0), "x: 3000000 units (3.00 M/s), 1.0 s")
      << "an unknown share: no percentage, no ETA";
  EXPECT_EQ(Progress::format_duration(7300), "2 h 02 min");
}

TEST(Cli, DumpLimitReadsNoFurtherThanItPrints) {
  CliSandbox box;
  // Unflagged traces are parsed record by record; a checksummed one block by block
  // (a block is verified before any of its records is handed on).
  expect_ok(box.run("scene enderton-1 --spp 4 --compression none --no-checksum -o e.trace"), "scene enderton-1");
  size_t header_bytes = 0, record_bytes = 0;
  {
    ropsim::TraceReader r(box.path("e.trace"));
    header_bytes = 48 + 2 * size_t(r.header().spp) + r.header().scene_name.size();
    record_bytes = ropsim::fragment_record_bytes(r.header(), 1);  // plane depth: any coverage
  }
  // Records 0..2 complete, record 3 cut short. With its fragment count the
  // cut trace is refused at open (the payload cannot hold it); with the
  // count zeroed (not recorded, as from a pipe) it is read record by record.
  const std::string full = slurp(box.path("e.trace"));
  const std::string cut = full.substr(0, header_bytes + 3 * record_bytes + 5);
  std::ofstream(box.path("counted.trace"), std::ios::binary) << cut;
  expect_cli_error(box, "trace dump counted.trace --limit 3", {"counted.trace: header: ", "bytes 42..47"});
  std::ofstream(box.path("cut.trace"), std::ios::binary) << cut.substr(0, 42) + std::string(6, '\0') + cut.substr(48);
  const CliResult r = box.run("trace dump cut.trace --limit 3");
  expect_ok(r, "trace dump --limit 3 of a trace whose record 3 is cut");
  EXPECT_EQ(lines_of(r.out).size(), 4u) << r.describe();
  expect_cli_error(box, "trace dump cut.trace --limit 4", {"cut.trace", "record 3:"});
}

// A negative --limit is refused in one line naming the flag (it wrapped to
// "everything" and exited 0).
TEST(Cli, DumpRefusesANegativeLimit) {
  CliSandbox box;
  expect_ok(box.run("scene cloth --spp 4 -o c.trace"), "scene cloth");
  expect_cli_error(box, "trace dump c.trace --limit -1", {"--limit", "-1", ">= 0"});
  expect_cli_error(box, "trace dump c.trace --limit -1 -o d.jsonl", {"--limit"});
  const CliResult r = box.run("trace dump c.trace --limit 0");
  expect_ok(r, "trace dump --limit 0");
  EXPECT_EQ(lines_of(r.out).size(), 1u) << "--limit 0: the header alone\n" << r.describe();
}

// Ranges read as a person writes them: ">= 1" for an open range, "8..32" for
// a closed one, in --help and in the error; never the type's largest value.
TEST(Cli, RangesInHelpAndErrorsAreReadable) {
  CliSandbox box;
  for (const char* verb : {"run", "livepoints", "scene", "capture", "trace dump", "vectors", "config", "study run"}) {
    const CliResult h = box.run(std::string(verb) + " --help");
    expect_ok(h, std::string(verb) + " --help");
    EXPECT_EQ(h.out.find("18446744073709551615"), std::string::npos) << verb << " --help\n" << h.out;
    EXPECT_EQ(h.out.find(" - 1099511627776]"), std::string::npos) << verb << " --help\n" << h.out;
  }
  const CliResult h = box.run("run --help");
  for (const char* shown : {"--stats-interval N:>= 1", "8..32"})
    EXPECT_NE(h.out.find(shown), std::string::npos) << "run --help lacks \"" << shown << "\"\n" << h.out;
  expect_cli_error(box, "run --fidelity cycle --stats-interval 0", {"--stats-interval", "must be >= 1"});
  expect_cli_error(box, "run --hash-bits 40", {"--hash-bits", "40", "must be in 8..32"});
  expect_cli_error(box, "vectors alpha-ref --count 0 -o v.csv", {"--count", "must be in 1..100000000"});
  for (const char* bad : {"run --fidelity cycle --stats-interval 0", "run --hash-bits 40", "trace dump x --limit -1"}) {
    const CliResult r = box.run(bad);
    EXPECT_EQ(r.err.find("18446744073709551615"), std::string::npos) << bad << "\n" << r.describe();
  }
}

// The main output of every verb that writes a file is -o/--out FILE (a study
// folder for study run, plan and task); the older spellings stay as aliases
// and write the same bytes.
TEST(Cli, EveryVerbTakesDashOOutForItsMainOutput) {
  CliSandbox box;
  for (const char* flag : {"-o", "--out", "--output"})
    expect_ok(box.run(std::string("scene smoke --spp 4 --width 64 --height 64 ") + flag + " s" + (flag + 1) + ".trace"),
              std::string("scene ") + flag);
  EXPECT_EQ(slurp(box.path("so.trace")), slurp(box.path("s-out.trace")));
  EXPECT_EQ(slurp(box.path("so.trace")), slurp(box.path("s-output.trace")));
  for (const char* flag : {"-o", "--out", "--output"}) {
    expect_ok(box.run(std::string("trace dump so.trace --limit 3 ") + flag + " d" + (flag + 1) + ".jsonl"),
              std::string("trace dump ") + flag);
    expect_ok(box.run(std::string("vectors tracker --count 10 ") + flag + " v" + (flag + 1) + ".csv"),
              std::string("vectors ") + flag);
  }
  EXPECT_EQ(slurp(box.path("do.jsonl")), slurp(box.path("d-out.jsonl")));
  EXPECT_EQ(slurp(box.path("vo.csv")), slurp(box.path("v-output.csv")));
  EXPECT_FALSE(slurp(box.path("d-output.jsonl")).empty());
  expect_ok(box.run("run --trace so.trace -o a.png --quiet"), "run -o");
  expect_ok(box.run("run --trace so.trace --out b.png --quiet"), "run --out");
  EXPECT_EQ(slurp(box.path("a.png")), slurp(box.path("b.png")));
  for (const char* verb : {"capture", "livepoints", "study run", "study plan", "study task", "study export"}) {
    const CliResult h = box.run(std::string(verb) + " --help");
    expect_ok(h, std::string(verb) + " --help");
    EXPECT_NE(h.out.find("-o,--out"), std::string::npos) << verb << " --help has no -o,--out\n" << h.out;
  }
}

// trace dump writes each covered sample's depth under its index in sample
// order (0, 2, 10, 11; as strings "10" and "11" would come before "2").
TEST(Cli, DumpWritesSampleDepthsInSampleOrder) {
  CliSandbox box;
  expect_ok(box.run("scene cloth --spp 16 -o c.trace"), "scene cloth");
  const CliResult r = box.run("trace dump c.trace --limit 200");
  expect_ok(r, "trace dump");
  const auto lines = lines_of(r.out);
  ASSERT_EQ(lines.size(), 201u) << r.describe();
  size_t mixed = 0;  // fragments with samples below 10 and from 10 on: string order would differ
  for (size_t i = 1; i < lines.size(); ++i) {
    const auto j = nlohmann::ordered_json::parse(lines[i]);  // keeps the keys in the order written
    ASSERT_TRUE(j["sample_depth"].is_object()) << lines[i];
    int last = -1;
    bool low = false, high = false;
    for (const auto& [key, depth] : j["sample_depth"].items()) {
      const int k = std::stoi(key);
      EXPECT_GT(k, last) << "sample_depth keys out of sample order: " << lines[i];
      last = k;
      (k < 10 ? low : high) = true;
      EXPECT_TRUE(depth.is_number()) << lines[i];
    }
    mixed += low && high;
  }
  EXPECT_GT(mixed, 0u) << "no fragment covered samples on both sides of 10: the check proves nothing";
}

// Every verb's --help ends with two or three examples, and each runs as
// written (exit 0) in a folder holding the checkout's configs/, studies/ and
// traces/: the verbs in an order where each example finds the files the ones
// before it wrote (the scene examples make cloth.trace, run's lk.exr and
// reference.exr, study run's st).
TEST(Cli, EveryVerbsHelpHasExamplesThatRun) {
  CliSandbox box;
  for (const char* d : {"configs", "studies", "traces"})
    fs::create_directory_symlink(fs::path(ROPSIM_SOURCE_DIR) / d, box.work() / d);
  const std::vector<std::string> verbs = {
      "scene",        "trace",      "trace info",   "trace validate", "trace dump", "trace kinds",   "capture",
      "run",          "livepoints", "compare",      "vectors",        "config",     "report-fields", "study",
      "study points", "study run",  "study export", "study plan",     "study task", "study collect", "study report"};
  std::set<std::string> ran;
  for (const auto& verb : verbs) {
    const CliResult h = box.run(verb + " --help");
    expect_ok(h, verb + " --help");
    const auto at = h.out.find("\nExamples:\n");
    ASSERT_NE(at, std::string::npos) << "ropsim " << verb << " --help has no examples\n" << h.out;
    std::vector<std::string> cmds;
    for (const auto& l : lines_of(h.out.substr(at + 11))) {
      if (l.rfind("  ropsim ", 0) != 0) break;
      std::string c = l.substr(9);
      if (const auto hash = c.find("   #"); hash != std::string::npos) c.erase(hash);
      cmds.push_back(c);
    }
    EXPECT_GE(cmds.size(), 2u) << "ropsim " << verb << " --help: two or three examples\n" << h.out;
    EXPECT_LE(cmds.size(), 3u) << "ropsim " << verb << " --help: two or three examples\n" << h.out;
    for (const auto& c : cmds) {
      if (!ran.insert(c).second) continue;
      const CliResult r = box.run(c);
      EXPECT_EQ(r.code, 0) << "the example of " << verb << " --help failed: ropsim " << c << "\n" << r.describe();
    }
  }
}

TEST(Cli, NoChecksumWritesTheBytesOfBeforeTheChecksum) {
  // fuzz/regressions/trace/ keeps two traces written before the checksum
  // existed (header flags 0): --no-checksum must reproduce them byte for byte,
  // uncompressed and zstd. The default writes the checksummed layout instead.
  CliSandbox box;
  const fs::path kept = fs::path(ROPSIM_SOURCE_DIR) / "fuzz" / "regressions" / "trace";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"scene eight-layers --width 8 --height 8 --spp 4 --compression none", "eight-layers-8x8-none.rtrace"},
      {"scene testcard --width 8 --height 8 --spp 4 --depth per-sample --color rgb-unorm8",
       "testcard-8x8-zstd-persample-unorm8.rtrace"}};
  for (const auto& [args, file] : cases) {
    const std::string before = slurp(kept / file);
    ASSERT_GT(before.size(), 48u) << file;
    ASSERT_EQ(before[10], 0) << file << " should be a trace without the checksum flag";
    expect_ok(box.run(args + " --no-checksum -o plain.trace"), args + " --no-checksum");
    // The same bytes but 42..47, where the writer now records the fragment
    // count (count + 1; the kept traces hold 0, "not recorded").
    const std::string plain = slurp(box.path("plain.trace"));
    ASSERT_EQ(plain.size(), before.size()) << args << " --no-checksum differs in size from " << file;
    EXPECT_EQ(ropsim_test::first_byte_difference(plain.substr(0, 42), before.substr(0, 42)), "")
        << args << " --no-checksum differs from " << file << " before bytes 42..47";
    EXPECT_EQ(ropsim_test::first_byte_difference(plain.substr(48), before.substr(48)), "")
        << args << " --no-checksum differs from " << file << " after bytes 42..47 (byte 0 is byte 48)";
    EXPECT_EQ(before.substr(42, 6), std::string(6, '\0')) << file;
    uint64_t field = 0;
    for (int i = 0; i < 6; ++i) field |= uint64_t(uint8_t(plain[size_t(42 + i)])) << (8 * i);
    const auto info = nlohmann::json::parse(box.run("trace info plain.trace --json").out);
    EXPECT_EQ(field, info["fragments"].get<uint64_t>() + 1) << "bytes 42..47 hold the fragment count + 1";
    EXPECT_EQ(info["header_fragment_count"], info["fragments"]);
    expect_ok(box.run(args + " -o ck.trace"), args);
    const std::string ck = slurp(box.path("ck.trace"));
    ASSERT_GT(ck.size(), 48u);
    EXPECT_EQ(ck[10], 3) << args << ": the default trace must carry the checksum and header check flags";
    const CliResult r = box.run("trace info ck.trace --json");
    expect_ok(r, "trace info --json");
    const auto j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j["checksum"].value("hash", ""), "xxh3-64") << r.out;
    EXPECT_EQ(j["checksum"].value("blocks", 0), 1) << r.out;
    EXPECT_EQ(j["header"].value("checksummed", false), true) << r.out;
    const CliResult p = box.run("trace info plain.trace --json");
    EXPECT_TRUE(nlohmann::json::parse(p.out)["checksum"].is_null()) << p.out;
    EXPECT_TRUE(box.run("trace info plain.trace").out.find("checksum none") != std::string::npos);
    fs::remove(box.path("plain.trace"));
    fs::remove(box.path("ck.trace"));
  }
}

TEST(Cli, SameInputsAndSeedGiveIdenticalOutputs) {
  CliSandbox a, b;
  const std::string args = "run --scene enderton-2 --spp 4 --out a.png --report r.json";
  expect_ok(a.run(args), args);
  expect_ok(b.run(args), args + " (again)");
  const std::string png_a = slurp(a.path("a.png")), png_b = slurp(b.path("a.png"));
  ASSERT_FALSE(png_a.empty()) << "no a.png";
  EXPECT_EQ(ropsim_test::first_byte_difference(png_a, png_b), "") << "two identical runs wrote different a.png";
  const auto ra = nlohmann::json::parse(slurp(a.path("r.json")));
  const auto rb = nlohmann::json::parse(slurp(b.path("r.json")));
  // Counter names of sim/report/report.cpp.
  for (const char* k :
       {"fragments", "samples_tested", "samples_depth_passed", "samples_opacity_passed", "samples_written",
        "surface_id_changes", "sorts", "depth_bytes_read", "depth_bytes_written", "color_bytes_written",
        "tracker_bytes_read", "tracker_bytes_written", "state_bytes_read", "state_bytes_written", "tiles_touched"}) {
    ASSERT_TRUE(ra["counters"].contains(k)) << "report lacks counters." << k << ": " << ra.dump();
    EXPECT_TRUE(ra["counters"][k].is_number_unsigned()) << "counters." << k << " = " << ra["counters"][k];
  }
  EXPECT_EQ(ra["counters"], rb["counters"]) << "counters differ between identical runs:\n"
                                            << ra["counters"].dump() << "\n"
                                            << rb["counters"].dump();
  EXPECT_GT(ra["counters"].value("fragments", uint64_t{0}), 0u) << ra.dump();
  EXPECT_EQ(ra.value("tool", ""), "ropsim");
  EXPECT_EQ(ra.value("method", ""), "lk");
  EXPECT_EQ(ra.value("seed", 0), 1);
  EXPECT_EQ(ra["input"].value("scene", ""), "enderton-2");
  EXPECT_EQ(ra["input"].value("spp", 0), 4);
  EXPECT_EQ(ra["outputs"], nlohmann::json({"a.png", "r.json"}));
  EXPECT_EQ(ra["numerics"], rb["numerics"]);
}

TEST(Cli, AlphaRefVectors) {
  CliSandbox box;
  const CliResult r = box.run("vectors alpha-ref --count 10 -o v.csv");
  expect_ok(r, "vectors alpha-ref --count 10");
  const auto rows = lines_of(slurp(box.path("v.csv")));
  ASSERT_EQ(rows.size(), 11u) << "a header row and 10 vectors expected";
  EXPECT_EQ(rows[0], "sample_id,pixel_id,surface_id,spp,hash_bits,index_hex,ref_hex");
  bool found = false;
  for (size_t i = 1; i < rows.size(); ++i) {
    std::vector<std::string> c;
    std::istringstream in(rows[i]);
    for (std::string f; std::getline(in, f, ',');) c.push_back(f);
    ASSERT_EQ(c.size(), 7u) << "row " << i << ": " << rows[i];
    if (c[1] == "12345" && c[2] == "678") {
      found = true;
      EXPECT_EQ(c[6], "2ed32d8e") << "ref_hex of pixel 12345, surface 678: " << rows[i];
    }
  }
  EXPECT_TRUE(found) << "no row for pixel 12345, surface 678";
  EXPECT_EQ(box.files(), (std::set<std::string>{"v.csv"})) << "vectors wrote other files";
}

// Vectors from a trace: the file has the random vectors' header and one row
// per call, the summary line says how many; bad requests are one-line
// errors that write nothing.
TEST(Cli, TraceVectors) {
  CliSandbox box;
  expect_ok(box.run("scene cloth --spp 4 --width 64 --height 64 -o c.trace"), "scene cloth");
  const CliResult r = box.run("vectors tracker --trace c.trace --window 8,8,40,40 -o t.csv");
  expect_ok(r, "vectors tracker --trace");
  const auto rows = lines_of(slurp(box.path("t.csv")));
  ASSERT_GT(rows.size(), 10u) << "a header row and the window's tracker updates expected";
  EXPECT_EQ(rows[0],
            "spp,surface_id_bits,covered_in_hex,surface_id_in,surviving_hex,new_surface,n,surface_id_out,"
            "covered_out_hex");
  EXPECT_NE(r.out.find("wrote t.csv: " + std::to_string(rows.size() - 1) + " vectors for tracker from c.trace"),
            std::string::npos)
      << r.describe();
  expect_ok(box.run("vectors depth-test --trace c.trace --method hashed --format hex -o d.hex"), "depth-test hex");
  expect_cli_error(box, "vectors tracker --trace c.trace --method enderton -o e.csv", {"tracker", "enderton"});
  expect_cli_error(box, "vectors half --trace c.trace -o h.csv", {"half"});
  expect_cli_error(box, "vectors depth-test --trace c.trace --method slab -o s.csv", {"slab"});
  expect_cli_error(box, "vectors tracker --trace c.trace --window 5,5,1,1 -o w.csv", {"--window"});
  expect_cli_error(box, "vectors tracker --trace c.trace --window 1,2,3 -o w.csv", {"--window", "x0,y0,x1,y1"});
  expect_cli_error(box, "vectors tracker --trace c.trace --count 5 -o n.csv", {"--count"});
  expect_cli_error(box, "vectors tracker --window 0,0,1,1 -o x.csv", {"--window", "--trace"});
  expect_cli_error(box, "vectors tracker --trace missing.trace -o x.csv", {"missing.trace"});
  EXPECT_EQ(box.files(), (std::set<std::string>{"c.trace", "t.csv", "d.hex"})) << "a failed request wrote a file";
}

}  // namespace

namespace {

// A GTKWave save file ropsim wrote beside waveform w of cycles first..last
// (docs/reports.md "Waveforms"): it names the VCD by its absolute path,
// starts the view at the window's first cycle zoomed to show the window,
// shows the clock and the cycle counter first, then every scope under a
// comment line naming it, each signal a variable of the VCD, every variable
// of the VCD shown. Returns the number of lines GTKWave shows.
size_t check_gtkw(const std::string& g, const ropsim_test::Vcd& w, const fs::path& vcd, uint64_t first, uint64_t last) {
  std::istringstream in(g);
  std::vector<std::string> signals, comments;
  std::string dumpfile;
  double zoom = 0;
  uint64_t start = ~uint64_t{0};
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("[dumpfile] ", 0) == 0)
      dumpfile = line.substr(11);
    else if (line.rfind("[timestart] ", 0) == 0)
      start = std::stoull(line.substr(12));
    else if (line[0] == '*')
      zoom = std::stod(line.substr(1));
    else if (line[0] == '-')
      comments.push_back(line.substr(1));
    else if (line[0] != '[' && line[0] != '@')
      signals.push_back(line);
  }
  EXPECT_EQ(dumpfile, "\"" + fs::absolute(vcd).lexically_normal().string() + "\"");
  EXPECT_EQ(start, first * 1000) << "[timestart] in ps: the window's first cycle (1000 ps per cycle)";
  const double shown = 3.30 * std::pow(2.0, -zoom), window = double(last - first + 1) * 1000;
  EXPECT_TRUE(shown >= window && shown <= 1.1 * window)
      << "the zoom shows " << shown << " ps of a " << window << " ps window";
  EXPECT_GE(signals.size(), 2u);
  if (signals.size() >= 2) {
    EXPECT_EQ(signals[0], "top.clk");
    EXPECT_EQ(signals[1], "top.cycle");
  }
  std::set<std::string> vars, shown_signals(signals.begin(), signals.end());
  for (const auto& v : w.vars) vars.insert(v.scope + "." + v.name);
  EXPECT_EQ(shown_signals, vars) << "the save file shows exactly the VCD's variables";
  EXPECT_EQ(shown_signals.size(), signals.size()) << "a signal shown twice";
  for (const auto& c : comments)
    EXPECT_TRUE(std::any_of(w.vars.begin(), w.vars.end(), [&](const auto& v) { return v.scope == "top." + c; }))
        << "a group for scope " << c << ", which has no variable";
  EXPECT_NE(std::find(comments.begin(), comments.end(), "rop0"), comments.end()) << "no rop0 group";
  return signals.size() + comments.size();
}
}  // namespace

// ------------------------------------------------------------------ cycle fidelity

TEST(CliCycle, CycleRunWritesTheFunctionalImageAndATimingReport) {
  CliSandbox box;
  expect_ok(box.run("run --scene eight-layers --spp 4 --quiet --out f.exr"), "functional run");
  expect_ok(
      box.run("run --fidelity cycle --hw '" ROPSIM_SOURCE_DIR "/configs/narrow.toml' --scene eight-layers --spp 4 "
              "--quiet --out c.exr --report c.json --vcd w.vcd --vcd-window 100:400"),
      "cycle run");
  const CliResult cmp = box.run("compare c.exr f.exr --json");
  EXPECT_NE(cmp.out.find("\"rmse_8bit\": 0.000000"), std::string::npos) << cmp.describe();
  const auto j = nlohmann::json::parse(slurp(box.work() / "c.json"));
  EXPECT_EQ(j["fidelity"], "cycle");
  const auto& t = j["timing"];
  for (const char* k : {"total_cycles", "frame_time_us", "fragments_per_clock", "samples_per_clock", "units", "fifos",
                        "cache", "dram", "bottleneck", "memory_bound"})
    EXPECT_TRUE(t.contains(k)) << "timing." << k << " missing";
  for (const char* b : {"depth", "color", "tracker"}) {
    EXPECT_TRUE(t["dram"].contains(b)) << "dram bytes per buffer: " << b;
    EXPECT_TRUE(t["cache"].contains(b)) << "cache hits per buffer: " << b;
  }
  for (const auto& u : t["units"])
    for (const char* a : {"busy", "idle", "input_starved", "output_blocked", "pixel_hazard", "memory"})
      EXPECT_TRUE(u["cycles"].contains(a)) << u["name"] << " lacks " << a;
  // The waveform (docs/reports.md "Waveforms"): time in clock cycles, the
  // activities by name, rop0's units and FIFOs in one scope, nothing outside
  // the window.
  const ropsim_test::Vcd w = ropsim_test::parse_vcd(slurp(box.work() / "w.vcd"));
  // A cycle is ten 100 ps time units (1 ns: GTKWave's ns are cycles), the
  // clock high in its first half.
  EXPECT_EQ(w.timescale, "100 ps");
  EXPECT_NE(w.comment.find("One clock cycle is ten time units of 100 ps"), std::string::npos) << w.comment;
  const int cycle = w.find("top", "cycle"), clk = w.find("top", "clk");
  ASSERT_GE(cycle, 0) << "no cycle counter";
  ASSERT_GE(clk, 0) << "no clock";
  ASSERT_EQ(w.stamps.size(), 602u) << "two time stamps per cycle of 100:400";
  EXPECT_EQ(w.stamps.front(), 1000u);
  EXPECT_EQ(w.stamps.back(), 4005u);
  const std::set<std::string> names = {"idle", "busy", "input_starved", "output_blocked", "pixel_hazard", "memory"};
  std::set<std::string> seen;
  size_t cycles_seen = 0;
  for (const auto& c : w.changes) {
    EXPECT_TRUE(c.time >= 1000 && c.time <= 4005) << "VCD change at " << c.time << ", outside the window 100:400";
    if (int(c.var) == clk) {
      EXPECT_EQ(c.value, c.time % 10 == 5 ? "0" : "1") << "clk at time " << c.time;
      continue;
    }
    EXPECT_EQ(c.time % 10, 0u) << "a change off the rising clock edge, at time " << c.time;
    if (int(c.var) == cycle) {
      ++cycles_seen;
      EXPECT_EQ(ropsim_test::Vcd::number(c.value), c.time / 10)
          << "the cycle counter is not the time: ten units, one clock";
    }
    const auto& v = w.vars[c.var];
    if (v.type == "string" && v.scope != "top.dram") {
      EXPECT_TRUE(names.count(c.value)) << v.scope << "." << v.name << " = '" << c.value << "', not an activity name";
      seen.insert(c.value);
    }
  }
  EXPECT_EQ(cycles_seen, 301u);
  EXPECT_GE(seen.size(), 3u) << "the window shows fewer than three different activities";
  for (const char* u : {"pixel_ordering", "depth_test", "coverage_tracker", "sample_sorter", "alpha_ref_gen",
                        "writeback", "fifo_input", "fifo_ordering_to_depth", "fifo_depth_out"})
    EXPECT_GE(w.find("top.rop0", u), 0) << "rop0's scope lacks " << u;
  for (const auto& f : box.files()) EXPECT_NE(f[0], '.') << "temporary file " << f << " left behind";
  EXPECT_EQ(t["host"]["decoupled"], true) << "a --vcd run keeps its temporal decoupling";
  check_gtkw(slurp(box.work() / "w.gtkw"), w, box.work() / "w.vcd", 100, 400);
  EXPECT_NE(std::find(j["outputs"].begin(), j["outputs"].end(), "w.gtkw"), j["outputs"].end()) << "w.gtkw not listed";
  // GTKWave itself opens the save file (headless, when it and xvfb-run are
  // installed): it finds the VCD, shows every line and the window.
  if (!fs::exists("/usr/bin/gtkwave") || !fs::exists("/usr/bin/xvfb-run")) return;
  std::ofstream(box.work() / "q.tcl") << "puts \"VIEW [gtkwave::getWindowStartTime] [gtkwave::getWindowEndTime] "
                                         "[gtkwave::getTotalNumTraces]\"\ngtkwave::/File/Quit\n";
  const std::string cmd = "cd '" + box.work().string() + "' && timeout 60 xvfb-run -a gtkwave -S q.tcl '" +
                          (box.work() / "w.gtkw").string() + "' > gtkwave.log 2>&1";
  const int rc = std::system(cmd.c_str());
  const std::string log = slurp(box.work() / "gtkwave.log");
  const auto at = log.find("VIEW ");
  ASSERT_NE(at, std::string::npos) << "GTKWave did not open w.gtkw (exit " << rc << "):\n" << log;
  std::istringstream view(log.substr(at + 5));
  uint64_t from = 0, to = 0, lines = 0;
  view >> from >> to >> lines;
  EXPECT_EQ(from, 100000u) << "the view starts at cycle 100 (ps)";
  EXPECT_TRUE(to >= 401000 && to <= 440000) << "the view ends at " << to << " ps, not just after cycle 400";
  EXPECT_EQ(lines, check_gtkw(slurp(box.work() / "w.gtkw"), w, box.work() / "w.vcd", 100, 400));
}

// A --vcd-window run is the run without --vcd: every timing figure, and the
// host cost (it stays decoupled before, in and after the window). Its
// waveform has one scope per ROP holding that ROP's units and the FIFOs they
// read; the shared units and the DRAM have their own.
TEST(CliCycle, WaveformWindowLeavesTheRunDecoupledAndUnchanged) {
  CliSandbox box;
  const std::string common = "run --fidelity cycle --scene cloth --spp 4 --quiet ";
  expect_ok(box.run(common + "--out p.exr --report p.json"), "cycle run");
  expect_ok(box.run(common + "--out v.exr --report v.json --vcd w.vcd --vcd-window 20000:21000"), "--vcd run");
  const auto p = nlohmann::json::parse(slurp(box.work() / "p.json"))["timing"];
  const auto v = nlohmann::json::parse(slurp(box.work() / "v.json"))["timing"];
  for (const char* k : {"total_cycles", "pipeline_cycles", "dram", "cache", "fifos"})
    EXPECT_EQ(p[k], v[k]) << "timing." << k << " differs with --vcd";
  ASSERT_EQ(p["units"].size(), v["units"].size());
  for (size_t i = 0; i < p["units"].size(); ++i)
    EXPECT_EQ(p["units"][i]["cycles"], v["units"][i]["cycles"]) << p["units"][i]["name"] << "'s activity cycles";
  EXPECT_EQ(v["host"]["decoupled"], true) << "the --vcd run was not decoupled";
  EXPECT_EQ(p["host"]["unit_runs"], v["host"]["unit_runs"]) << "the --vcd run ran its units more often (lockstep?)";
  EXPECT_EQ(p["host"]["systemc_activations"], v["host"]["systemc_activations"]);

  const ropsim_test::Vcd w = ropsim_test::parse_vcd(slurp(box.work() / "w.vcd"));
  ASSERT_FALSE(w.stamps.empty());
  EXPECT_EQ(w.stamps.front(), 200000u) << "cycle 20000's rising edge";
  EXPECT_EQ(w.stamps.back(), 210005u) << "cycle 21000's falling edge";
  for (const auto& c : w.changes) ASSERT_TRUE(c.time >= 200000 && c.time <= 210005) << "a change at " << c.time;
  std::set<std::string> rops;
  for (const auto& u : v["units"]) {
    const int rop = u["rop"].get<int>();
    const std::string kind = u["kind"], scope = rop >= 0 ? "top.rop" + std::to_string(rop) : "top." + kind;
    if (rop >= 0) rops.insert(scope);
    const int var = w.find(scope, kind);
    ASSERT_GE(var, 0) << u["name"] << " is not " << scope << "." << kind;
    EXPECT_EQ(w.vars[size_t(var)].type, "string") << scope << "." << kind;
  }
  ASSERT_GE(rops.size(), 2u) << "the test needs several ROPs";
  for (const auto& f : v["fifos"]) {
    const std::string n = f["name"];
    const auto dot = n.find('.');
    if (dot == std::string::npos) continue;  // source_to_distributor: the distributor's
    EXPECT_GE(w.find("top." + n.substr(0, dot), "fifo_" + n.substr(dot + 1)), 0) << "FIFO " << n;
  }
  std::set<std::string> scopes;
  for (const auto& var : w.vars) scopes.insert(var.scope);
  std::set<std::string> expected = rops;
  expected.insert({"top", "top.trace_source", "top.distributor", "top.dram"});
  EXPECT_EQ(scopes, expected) << "scopes other than the ROPs, the shared units and the DRAM";
  EXPECT_GE(w.find("top.dram", "ch0_bus"), 0);
  EXPECT_GE(w.find("top.dram", "ch0_row_misses"), 0);
}

// --lockstep gives the decoupled run's image and report (narrow.toml has one
// ROP, where the two modes agree in every timing figure), with more activations.
TEST(CliCycle, LockstepFlagGivesTheSameRun) {
  CliSandbox box;
  const std::string common =
      "run --fidelity cycle --hw '" ROPSIM_SOURCE_DIR "/configs/narrow.toml' --scene cloth --spp 4 --quiet ";
  expect_ok(box.run(common + "--out d.exr --report d.json"), "decoupled run");
  expect_ok(box.run(common + "--lockstep --out l.exr --report l.json"), "lockstep run");
  const CliResult cmp = box.run("compare d.exr l.exr --json");
  EXPECT_NE(cmp.out.find("\"rmse_8bit\": 0.000000"), std::string::npos) << cmp.describe();
  const auto d = nlohmann::json::parse(slurp(box.work() / "d.json"))["timing"];
  const auto l = nlohmann::json::parse(slurp(box.work() / "l.json"))["timing"];
  EXPECT_EQ(d["host"]["decoupled"], true);
  EXPECT_EQ(l["host"]["decoupled"], false);
  EXPECT_EQ(d["total_cycles"], l["total_cycles"]);
  EXPECT_EQ(d["dram"], l["dram"]);
  EXPECT_LT(d["host"]["unit_runs"].get<double>(), l["host"]["unit_runs"].get<double>());
  expect_cli_error(box, "run --lockstep --scene testcard --spp 1", {"--lockstep", "cycle"});
}

TEST(CliCycle, StatsIntervalWritesACsvWhoseRowsAddUpToTheReport) {
  CliSandbox box;
  expect_ok(box.run("run --fidelity cycle --scene cloth --spp 4 --quiet --stats-interval 1000 --stats-csv s/i.csv "
                    "--report r.json --out r.exr"),
            "cycle run with --stats-interval");
  const auto rep = nlohmann::json::parse(slurp(box.work() / "r.json"));
  std::istringstream csv(slurp(box.work() / "s/i.csv"));
  std::string header;
  ASSERT_TRUE(std::getline(csv, header));
  std::vector<std::string> cols;
  for (size_t a = 0, b; a <= header.size(); a = b + 1) {
    b = header.find(',', a);
    if (b == std::string::npos) b = header.size();
    cols.push_back(header.substr(a, b - a));
  }
  auto col = [&](const std::string& name) {
    auto it = std::find(cols.begin(), cols.end(), name);
    EXPECT_NE(it, cols.end()) << name << " is a column of " << header;
    return size_t(it - cols.begin());
  };
  const size_t end_c = col("cycle_end"), frag_c = col("fragments_retired"), dr = col("dram_bytes_read.depth"),
               busy = col("depth_test.busy");
  uint64_t frags = 0, depth_read = 0, rows = 0, last_end = 0, busy_cycles = 0;
  for (std::string line; std::getline(csv, line); ++rows) {
    std::vector<std::string> v;
    std::stringstream ls(line);
    for (std::string x; std::getline(ls, x, ',');) v.push_back(x);
    ASSERT_GT(v.size(), busy) << line;
    frags += std::stoull(v[frag_c]);
    depth_read += std::stoull(v[dr]);
    busy_cycles += std::stoull(v[busy]);
    last_end = std::stoull(v[end_c]);
  }
  EXPECT_EQ(frags, rep["counters"]["fragments"].get<uint64_t>());
  EXPECT_EQ(depth_read, rep["timing"]["dram"]["depth"]["bytes_read"].get<uint64_t>());
  EXPECT_EQ(last_end, rep["timing"]["total_cycles"].get<uint64_t>()) << "the last row ends with the run";
  EXPECT_EQ(rows, (last_end + 999) / 1000);
  EXPECT_GT(busy_cycles, 0u);
  expect_cli_error(box, "run --fidelity cycle --scene testcard --spp 1 --stats-interval 100", {"--stats-csv"});
  expect_cli_error(box, "run --scene testcard --spp 1 --stats-interval 100 --stats-csv x.csv",
                   {"--stats-interval", "cycle"});
  expect_cli_error(box, "run --fidelity cycle --scene testcard --spp 1 --stats-interval 0 --stats-csv x.csv",
                   {"--stats-interval"});
  EXPECT_FALSE(std::filesystem::exists(box.work() / "x.csv"));
}

// --threads changes how fast the golden model runs, never a bit of what it
// writes: the images are byte-identical and the reports differ only in the
// host figures and the command line.
TEST(Cli, ThreadCountsWriteTheSameFiles) {
  CliSandbox box;
  for (const char* t : {"1", "2", "5"})
    expect_ok(box.run(std::string("--threads ") + t + " run --scene smoke --spp 16 --vs-reference --quiet --out t" + t +
                      ".exr --out t" + t + ".png --report t" + t + ".json"),
              std::string("--threads ") + t);
  for (const char* t : {"2", "5"}) {
    for (const char* ext : {".exr", ".png"})
      EXPECT_EQ(slurp(box.work() / (std::string("t1") + ext)), slurp(box.work() / (std::string("t") + t + ext)))
          << "--threads " << t << " " << ext;
    auto a = nlohmann::json::parse(slurp(box.work() / "t1.json")),
         b = nlohmann::json::parse(slurp(box.work() / (std::string("t") + t + ".json")));
    EXPECT_EQ(b["host"]["threads"], std::stoi(t));
    for (auto* j : {&a, &b}) {
      j->erase("host");
      j->erase("command");
      j->erase("outputs");
    }
    EXPECT_EQ(a.dump(1), b.dump(1)) << "--threads " << t;
  }
  expect_cli_error(box, "run --threads 0 --scene testcard --spp 1", {"--threads"});
}

// --fidelity sampled writes the golden image bit for bit and estimates under
// the cycle report's keys with their intervals.
TEST(CliCycle, SampledRunWritesTheGoldenImageAndEstimatesWithIntervals) {
  CliSandbox box;
  expect_ok(box.run("run --scene cloth --spp 16 --quiet --out f.exr --out f.png --report f.json"), "functional");
  expect_ok(box.run("run --fidelity sampled --scene cloth --spp 16 --quiet --sample-units 8 --sample-size 1000 "
                    "--out s.exr --out s.png --report s.json"),
            "sampled");
  EXPECT_EQ(slurp(box.work() / "f.exr"), slurp(box.work() / "s.exr")) << "the sampled run writes the golden image";
  EXPECT_EQ(slurp(box.work() / "f.png"), slurp(box.work() / "s.png"));
  const auto f = nlohmann::json::parse(slurp(box.work() / "f.json"));
  const auto s = nlohmann::json::parse(slurp(box.work() / "s.json"));
  EXPECT_EQ(s["fidelity"], "sampled");
  EXPECT_EQ(s["counters"], f["counters"]) << "the golden model's counters, exactly";
  const auto& t = s["timing"];
  for (const auto& [v, ci] : {std::pair{t["total_cycles"], t["total_cycles_ci95"]},
                              {t["dram"]["bytes_read"], t["dram"]["bytes_read_ci95"]},
                              {t["dram"]["bytes_written"], t["dram"]["bytes_written_ci95"]}}) {
    ASSERT_TRUE(ci.is_array() && ci.size() == 2) << ci;
    EXPECT_LE(ci[0].get<double>(), v.get<double>());
    EXPECT_LE(v.get<double>(), ci[1].get<double>());
    EXPECT_GT(v.get<double>(), 0.0);
  }
  EXPECT_EQ(t["sampling"]["units"], 8);
  EXPECT_EQ(t["sampling"]["unit_fragments"], 1000);
  EXPECT_EQ(t["sampling"]["fragments"], f["counters"]["fragments"]);
  EXPECT_LE(t["sampling"]["fragments_detailed"].get<uint64_t>(), f["counters"]["fragments"].get<uint64_t>());
  expect_cli_error(box, "run --scene testcard --spp 1 --sample-units 3", {"--sample-units", "sampled"});
  expect_cli_error(box, "run --fidelity sampled --scene testcard --spp 1 --vcd w.vcd", {"--vcd", "sampled"});
  expect_cli_error(box, "run --fidelity sampled --scene testcard --spp 4 --method lk+ac", {"lk+ac"});
  expect_cli_error(box, "run --fidelity sampled --scene testcard --spp 4 --sample-size 0", {"--sample-size"});
}

// The per-draw table and the per-pixel maps come from the functional and the
// cycle runs; the approximate and the sampled fidelities make neither, so the
// flags are refused there rather than ignored.
TEST(CliCycle, BreakdownFlagsAreRefusedWhereTheFidelityHasNoBreakdown) {
  CliSandbox box;
  for (const char* fidelity : {"approximate", "sampled"})
    for (const char* flag : {"--per-draw", "--draw-csv d.csv", "--maps m"}) {
      const std::string f = flag;
      expect_cli_error(box, std::string("run --fidelity ") + fidelity + " --scene testcard --spp 4 " + f,
                       {f.substr(0, f.find(' ')), fidelity});
    }
  EXPECT_FALSE(std::filesystem::exists(box.work() / "d.csv"));
  EXPECT_FALSE(std::filesystem::exists(box.work() / "m"));
}

// A trace whose header claims more fragments than its payload can hold --
// 2^48 - 2, or the count with one bit of byte 47 flipped -- is refused by
// `livepoints` and by `run --fidelity sampled --trace` when it is opened,
// exit 1, one line naming the file and the field, within --memory-limit 512M
// (not by the allocator, after growing in proportion to the claim). A
// checksummed trace's header check finds the flip; a trace without one
// (--no-checksum, older writers) is bounded by its size.
TEST(CliCycle, AFragmentCountThePayloadCannotHoldIsRefused) {
  CliSandbox box;
  expect_ok(box.run("scene smoke --spp 4 -o checked.rtr"), "scene");
  expect_ok(box.run("scene smoke --spp 4 --no-checksum -o plain.rtr"), "scene --no-checksum");
  for (const std::string base : {"checked.rtr", "plain.rtr"}) {
    const std::string bytes = slurp(box.work() / base);
    ASSERT_GT(bytes.size(), 48u);
    EXPECT_EQ(bytes[10], base == "checked.rtr" ? 3 : 0) << base << ": flags";
    uint64_t field = 0;
    for (int i = 0; i < 6; ++i) field |= uint64_t(uint8_t(bytes[size_t(42 + i)])) << (8 * i);
    for (const uint64_t lie : {(uint64_t{1} << 48) - 1, field ^ (uint64_t{1} << 47)}) {
      SCOPED_TRACE(base + ", bytes 42..47 = " + std::to_string(lie));
      std::string forged = bytes;
      for (int i = 0; i < 6; ++i) forged[size_t(42 + i)] = char(uint8_t(lie >> (8 * i)));
      std::ofstream(box.path("lie.rtr"), std::ios::binary) << forged;
      for (const std::string args : {"--memory-limit 512M livepoints lie.rtr -o L.rlp",
                                     "--memory-limit 512M run --fidelity sampled --trace "
                                     "lie.rtr --quiet --out o.exr"}) {
        const CliResult r = box.run(args);
        EXPECT_EQ(r.code, 1) << args << "\n" << r.describe();
        expect_cli_error(box, args, {"lie.rtr: header: ", "bytes 42..47"});
      }
    }
  }
}

// `ropsim livepoints` records once; `run --fidelity sampled --livepoints LIB`
// then serves each design without the trace (it is moved away), with the
// estimates of a run that recorded its own live-points, the golden image, and
// the same figures for any -j. Another trace, method or sampling is refused.
TEST(CliCycle, LivePointLibraryServesDesignsWithoutTheTrace) {
  CliSandbox box;
  expect_ok(box.run("scene cloth --spp 16 -o c.rtr"), "scene");
  expect_ok(box.run("scene smoke --spp 16 -o other.rtr"), "scene");
  const std::string sampling = " --sample-units 6 --sample-size 1000 --sample-warmup 1500";
  expect_ok(box.run("livepoints c.rtr -o c.rlp --quiet" + sampling), "livepoints");
  expect_ok(box.run("run --fidelity sampled --trace c.rtr -j 1 --quiet --out own.exr --report own.json" + sampling),
            "sampled run recording its own live-points");
  expect_ok(box.run("run --trace c.rtr --quiet --out golden.exr"), "functional");
  fs::rename(box.work() / "c.rtr", box.work() / "moved.rtr");
  const auto own = nlohmann::json::parse(slurp(box.work() / "own.json"));
  for (const char* design : {"default", "narrow", "wide"}) {
    const std::string d = design;
    expect_ok(box.run("run --fidelity sampled --livepoints c.rlp -j 2 --quiet --hw " + std::string(ROPSIM_SOURCE_DIR) +
                      "/configs/" + d + ".toml --out " + d + ".exr --report " + d + ".json"),
              "sampled from the library on " + d);
    EXPECT_EQ(slurp(box.work() / (d + ".exr")), slurp(box.work() / "golden.exr")) << d << ": the golden image";
    const auto r = nlohmann::json::parse(slurp(box.work() / (d + ".json")));
    EXPECT_EQ(r["timing"]["sampling"]["library"], "c.rlp");
    EXPECT_EQ(r["input"]["trace"], "c.rtr") << "the report names the library's input";
    EXPECT_EQ(r["host"]["sampled_jobs"], 2);
    if (d == "default") {
      EXPECT_EQ(r["timing"]["total_cycles"], own["timing"]["total_cycles"]);
      EXPECT_EQ(r["timing"]["total_cycles_ci95"], own["timing"]["total_cycles_ci95"]);
      EXPECT_EQ(r["timing"]["dram"], own["timing"]["dram"]);
      EXPECT_EQ(r["timing"]["bottleneck"], own["timing"]["bottleneck"]);
      EXPECT_EQ(r["timing"]["units"], own["timing"]["units"]);
      EXPECT_EQ(r["counters"], own["counters"]);
    }
  }
  expect_cli_error(box, "run --fidelity sampled --livepoints c.rlp --trace other.rtr", {"c.rlp", "other.rtr"});
  expect_cli_error(box, "run --fidelity sampled --livepoints c.rlp --method enderton", {"c.rlp", "enderton"});
  expect_cli_error(box, "run --fidelity sampled --livepoints c.rlp --hash-bits 16", {"c.rlp", "hash_bits"});
  expect_cli_error(box, "run --fidelity sampled --livepoints c.rlp --sample-units 3", {"--sample-units", "library"});
  expect_cli_error(box, "run --fidelity sampled --livepoints other.rtr", {"other.rtr", "not a live-point library"});
  expect_cli_error(box, "run --livepoints c.rlp", {"--livepoints", "sampled"});
  expect_cli_error(box, "run --fidelity cycle -j 2", {"--jobs", "sampled"});
  expect_cli_error(box, "livepoints other.rtr -o x.rlp --hw-set distributor.rop_units=8", {"--hw-set", "numerics"});
  expect_cli_error(box, "livepoints other.rtr -o x.rlp --method wboit", {"wboit"});
}

TEST(CliCycle, BadCycleFlagsFailInOneLine) {
  CliSandbox box;
  expect_cli_error(box, "run --hw nope.toml --scene testcard --spp 1", {"--hw"});
  expect_cli_error(box, "run --fidelity cycle --scene testcard --spp 1 --vcd w.vcd --vcd-window 9:3", {"--vcd-window"});
  expect_cli_error(box, "run --fidelity cycle --scene testcard --spp 1 --vcd-window 1:3", {"--vcd"});
  expect_cli_error(box, "run --fidelity cycle --scene testcard --spp 1 --hw-set dram.chanels=2", {"dram.chanels"});
  expect_cli_error(box, "run --fidelity cycle --scene testcard --spp 1 --hw-set dram.channels=0", {"dram.channels"});
  expect_cli_error(box, "run --fidelity cycle --method reference --scene testcard --spp 1", {"reference"});
  expect_cli_error(box, "run --scene testcard --spp 1 --hw-set dram.channels=2", {"--hw-set", "cycle"});
  { std::ofstream(box.path("bad.toml")) << "[cache]\nways = 3\n"; }
  expect_cli_error(box, "run --fidelity cycle --hw bad.toml --scene testcard --spp 1 --out x.png",
                   {"bad.toml", "cache."});
}

// --hw-set: a rejected override names itself; the cache shape is checked
// after the last override, so overrides valid only together are accepted.
TEST(CliCycle, HwSetOverridesAreCheckedTogether) {
  CliSandbox box;
  expect_cli_error(box, "run --fidelity cycle --scene testcard --spp 1 --out x.png --hw-set cache.ways=3",
                   {"--hw-set cache.ways=3: ", "power-of-two number of sets"});
  expect_cli_error(box, "run --fidelity cycle --scene testcard --spp 1 --out x.png --hw-set cache.size_bytes=256",
                   {"--hw-set cache.size_bytes=256: ", "smaller than one set"});
  const CliResult r = box.run(
      "run --fidelity cycle --scene testcard --spp 1 --out x.png --quiet --hw-set cache.size_bytes=256 "
      "--hw-set cache.ways=4");
  EXPECT_EQ(r.code, 0) << r.describe();
}

TEST(CliCycle, ConfigCommandPrintsTheDocumentedTable) {
  CliSandbox box;
  const CliResult r = box.run("config --markdown");
  expect_ok(r, "config --markdown");
  const std::string doc = slurp(fs::path(ROPSIM_SOURCE_DIR) / "docs" / "config.md");
  EXPECT_NE(doc.find(r.out), std::string::npos) << "docs/config.md is out of date: regenerate its table with "
                                                   "`ropsim config --markdown`";
}

// ------------------------------------------------------------ numerics in the design, names, JSON

// The design file's [numerics] are the run's numerics unless a run flag says
// otherwise, in both fidelities; a functional run takes only numerics.* keys.
TEST(CliNumerics, DesignFileNumericsEqualTheFlagsAndFlagsOverrideThem) {
  CliSandbox box;
  { std::ofstream(box.path("n12.toml")) << "[numerics]\nhash_bits = 12\n"; }
  const std::string scene = "run --scene smoke --spp 4 --quiet ";
  expect_ok(box.run(scene + "--hw n12.toml --out file.png --report file.json"), "functional --hw n12.toml");
  expect_ok(box.run(scene + "--hash-bits 12 --out flag.png"), "functional --hash-bits 12");
  expect_ok(box.run(scene + "--hw-set numerics.hash_bits=12 --out set.png"), "functional --hw-set numerics.hash_bits");
  expect_ok(box.run(scene + "--out default.png"), "functional, default numerics");
  EXPECT_EQ(slurp(box.path("file.png")), slurp(box.path("flag.png"))) << "[numerics] hash_bits = 12 != --hash-bits 12";
  EXPECT_EQ(slurp(box.path("set.png")), slurp(box.path("flag.png")));
  EXPECT_NE(slurp(box.path("file.png")), slurp(box.path("default.png"))) << "hash_bits 12 changed nothing";
  EXPECT_EQ(nlohmann::json::parse(slurp(box.path("file.json")))["numerics"]["hash_bits"], 12);
  // An explicit flag overrides the file.
  expect_ok(box.run(scene + "--hw n12.toml --hash-bits 32 --out over.png --report over.json"), "flag over file");
  EXPECT_EQ(slurp(box.path("over.png")), slurp(box.path("default.png")));
  EXPECT_EQ(nlohmann::json::parse(slurp(box.path("over.json")))["numerics"]["hash_bits"], 32);
  // The cycle fidelity: the same image, and the report's design shows the numerics that ran.
  expect_ok(box.run(scene + "--fidelity cycle --hw n12.toml --out cyc.png --report cyc.json"), "cycle --hw n12.toml");
  EXPECT_EQ(slurp(box.path("cyc.png")), slurp(box.path("flag.png")));
  const auto cyc = nlohmann::json::parse(slurp(box.path("cyc.json")));
  EXPECT_EQ(cyc["numerics"]["hash_bits"], 12);
  EXPECT_EQ(cyc["hardware"]["resolved"]["numerics"]["hash_bits"], 12);
  expect_ok(box.run(scene + "--fidelity cycle --hw n12.toml --hash-bits 20 --report cyc20.json"), "cycle flag");
  const auto cyc20 = nlohmann::json::parse(slurp(box.path("cyc20.json")));
  EXPECT_EQ(cyc20["numerics"]["hash_bits"], 20);
  EXPECT_EQ(cyc20["hardware"]["resolved"]["numerics"]["hash_bits"], 20);
  // A bad value names the key; a functional run refuses timing keys.
  { std::ofstream(box.path("bad.toml")) << "[numerics]\nhash_bits = 40\n"; }
  expect_cli_error(box, scene + "--hw bad.toml --out x.png", {"bad.toml", "numerics.hash_bits", "40"});
  expect_cli_error(box, scene + "--hw-set numerics.alpha_bits=0 --out x.png", {"numerics.alpha_bits=0"});
  expect_cli_error(box, scene + "--hw-set numerics.surface_id_bits=x --out x.png", {"numerics.surface_id_bits"});
  expect_cli_error(box, scene + "--hw-set cache.ways=4 --out x.png", {"--hw-set cache.ways=4", "cycle"});
}

// Default output names: a cycle run's carries a digest of the design, a
// functional run's its numerics when they are not the defaults.
TEST(CliNumerics, DefaultNamesNeverShareADesign) {
  CliSandbox box;
  const std::string scene = "run --scene smoke --spp 4 --quiet ";
  expect_ok(box.run(scene + "--fidelity cycle --hw-set distributor.rop_units=2"), "cycle, 2 ROPs");
  expect_ok(box.run(scene + "--fidelity cycle --hw-set distributor.rop_units=8"), "cycle, 8 ROPs");
  expect_ok(box.run(scene + "--fidelity cycle --hw-set distributor.rop_units=8"), "cycle, 8 ROPs again");
  expect_ok(box.run(scene + "--fidelity cycle --hw-set numerics.hash_bits=16"), "cycle, 16-bit hash");
  expect_ok(box.run(scene + "--fidelity cycle --hash-bits 16"), "cycle, --hash-bits 16");
  expect_ok(box.run(scene), "functional");
  expect_ok(box.run(scene + "--hash-bits 12"), "functional --hash-bits 12");
  std::set<std::string> reports;
  for (const auto& f : box.files())
    if (fs::path(f).extension() == ".json") reports.insert(fs::path(f).filename().string());
  // rop_units 2, rop_units 8 (twice: one name), hash 16 (flag or key: one design), functional x 2.
  ASSERT_EQ(reports.size(), 5u) << ::testing::PrintToString(reports);
  EXPECT_TRUE(reports.count("smoke-lk-4spp.json")) << ::testing::PrintToString(reports);
  EXPECT_TRUE(reports.count("smoke-lk-4spp-h12a32s32.json")) << ::testing::PrintToString(reports);
  for (const auto& r : reports) {
    if (r.find("-cycle-") == std::string::npos) continue;
    const auto j = nlohmann::json::parse(slurp(box.work() / "out" / "run" / r));
    const std::string digest = j["hardware"]["digest"];
    EXPECT_EQ(digest.size(), 8u);
    EXPECT_EQ(r, "smoke-lk-4spp-cycle-hw" + digest + ".json");
    EXPECT_TRUE(j["hardware"]["overrides"].is_array());
    EXPECT_LE(j["hardware"]["overrides"].size(), 1u) << j["hardware"].dump();  // the flag run has none
  }
}

// A functional run reports the final surfaces' compressibility only with
// --compressibility (its store then keeps each depth's plane key), under
// the design's [compression]; the flag is refused, in one line, for a timing
// fidelity and for a design that compresses nothing.
TEST(CliNumerics, CompressibilityIsMeasuredWhenAsked) {
  CliSandbox box;
  const std::string run = "run --scene smoke --spp 4 --width 64 --height 64 --quiet --out o.png ";
  expect_ok(box.run(run + "--report plain.json"), "functional run");
  EXPECT_FALSE(nlohmann::json::parse(slurp(box.path("plain.json"))).contains("compressibility"))
      << "measured without --compressibility";
  expect_ok(box.run(run + "--compressibility --report c.json"), "--compressibility");
  const auto c = nlohmann::json::parse(slurp(box.path("c.json")));
  ASSERT_TRUE(c.contains("compressibility")) << c.dump();
  EXPECT_EQ(c["compressibility"]["depth_encoder"], "plane");
  EXPECT_EQ(c["compressibility"]["buffers"].size(), 2u) << "depth and colour";
  expect_ok(box.run(run + "--compressibility --hw-set compression.depth_encoder=fit --report f.json"), "fit");
  EXPECT_EQ(nlohmann::json::parse(slurp(box.path("f.json")))["compressibility"]["depth_encoder"], "fit");
  expect_cli_error(box, run + "--compressibility --fidelity cycle --report x.json",
                   {"--compressibility", "--fidelity functional"});
  expect_cli_error(box,
                   run + "--compressibility --hw '" ROPSIM_SOURCE_DIR "/configs/uncompressed.toml' --report x.json",
                   {"--compressibility", "uncompressed.toml"});
}

// `config --json` is the design a run resolves (hardware.resolved), and
// `trace info --json` carries what `trace info` prints.
TEST(CliNumerics, ConfigAndTraceInfoAsJson) {
  CliSandbox box;
  CliResult r = box.run("config --json --hw-set dram.channels=2 --hw-set numerics.alpha_bits=8");
  expect_ok(r, "config --json");
  nlohmann::json cfg;
  ASSERT_NO_THROW(cfg = nlohmann::json::parse(r.out)) << r.describe();
  ASSERT_TRUE(cfg["memory_estimate"]["total_bytes"].is_number_unsigned()) << r.out;
  cfg.erase("memory_estimate");  // the design's model, not a parameter (tests/test_memory_estimate.cpp)
  EXPECT_EQ(cfg["dram"]["channels"], 2);
  EXPECT_EQ(cfg["numerics"]["alpha_bits"], 8);
  EXPECT_EQ(cfg["sorter"]["kind"], "bitonic");
  EXPECT_EQ(cfg["cache"]["fast_clear"], true);
  EXPECT_EQ(cfg["clock"]["frequency_ghz"], 1.5);
  // The default design is a current GPU's: compression (depth with the
  // rasterizer's planes) and Hi-Z on.
  EXPECT_EQ(cfg["compression"]["depth"], true);
  EXPECT_EQ(cfg["compression"]["color"], true);
  EXPECT_EQ(cfg["compression"]["depth_encoder"], "plane");
  EXPECT_EQ(cfg["hiz"]["enable"], true);
  r = box.run("config --json '" ROPSIM_SOURCE_DIR "/configs/narrow.toml'");
  expect_ok(r, "config --json narrow.toml");
  EXPECT_EQ(nlohmann::json::parse(r.out)["distributor"]["rop_units"], 1);
  expect_ok(box.run("run --scene smoke --spp 4 --quiet --fidelity cycle --hw-set dram.channels=2 --hw-set "
                    "numerics.alpha_bits=8 --report c.json"),
            "cycle run");
  const auto rep = nlohmann::json::parse(slurp(box.path("c.json")));
  EXPECT_EQ(rep["hardware"]["resolved"], cfg) << "the report's design is not config --json's";
  EXPECT_EQ(rep["hardware"]["overrides"], nlohmann::json({"dram.channels=2", "numerics.alpha_bits=8"}));
  expect_cli_error(box, "config --json --hw-set dram.channels=0", {"--hw-set dram.channels=0"});

  expect_ok(box.run("scene cloth --spp 4 -o c.trace"), "scene cloth");
  const CliResult text = box.run("trace info c.trace");
  r = box.run("trace info c.trace --json");
  expect_ok(r, "trace info --json");
  nlohmann::json t;
  ASSERT_NO_THROW(t = nlohmann::json::parse(r.out)) << r.describe();
  EXPECT_EQ(t["file"], "c.trace");
  EXPECT_EQ(t["header"]["scene"], "cloth");
  EXPECT_EQ(t["header"]["spp"], 4);
  EXPECT_EQ(t["header"]["width"], 256);
  ropsim::TraceReader reader(box.path("c.trace"));
  uint64_t n = 0;
  for (ropsim::Fragment f; reader.next(f);) ++n;
  EXPECT_EQ(t["fragments"], n);
  for (const char* k : {"covered_samples", "covered_samples_per_fragment", "draws", "bytes", "pixels_touched",
                        "pixels_touched_percent", "fragments_per_touched_pixel", "depth_complexity_histogram_pixels"})
    EXPECT_TRUE(t.contains(k)) << "trace info --json lacks " << k << "\n" << r.out;
  // The full histogram (it saturated at 16+ before): exact counts, whose
  // largest is the deepest pixel's, and which weighted by their count give
  // every fragment.
  uint64_t hist = 0, weighted = 0, deepest = 0;
  for (const auto& [k, v] : t["depth_complexity_histogram_pixels"].items()) {
    hist += v.get<uint64_t>();
    weighted += std::stoull(k) * v.get<uint64_t>();
    deepest = std::max<uint64_t>(deepest, std::stoull(k));
  }
  EXPECT_EQ(hist, t["pixels_touched"].get<uint64_t>());
  EXPECT_EQ(weighted, n) << "sum of k x pixels with k fragments = fragments";
  EXPECT_EQ(deepest, t["fragments_per_touched_pixel"]["max"].get<uint64_t>());
  EXPECT_GT(deepest, 16u) << "cloth has pixels deeper than 16: the histogram must not saturate";
  EXPECT_NE(text.out.find("fragments " + std::to_string(n) + " "), std::string::npos) << text.describe();
  EXPECT_NE(text.out.find("pixels touched " + std::to_string(t["pixels_touched"].get<uint64_t>()) + " "),
            std::string::npos)
      << text.describe();
}

// ------------------------------------------------------------------ blend methods

// The blend methods' names parse on the command line, their reports name the
// passes, the render-target formats and enderton's selection; the formats are
// the functional part of a design; --vcd refuses a multi-pass method.
TEST(CliBlend, MethodsParseAndReportTheirPassesFormatsAndSelection) {
  CliSandbox box;
  expect_ok(box.run("run --scene eight-layers --spp 4 --method lk+ac --quiet --out a.png --report a.json"), "lk+ac");
  auto j = nlohmann::json::parse(slurp(box.work() / "a.json"));
  EXPECT_EQ(j["method"], "lk+ac");
  EXPECT_EQ(j["passes"], nlohmann::json::array({"total_alpha", "stochastic"}));
  EXPECT_EQ(j["render_targets"]["transmittance"], "r16f");
  EXPECT_FALSE(j.contains("enderton_selection")) << "lk has no enderton selection";
  expect_ok(box.run("run --scene eight-layers --spp 4 --method wboit --hw-set blend.accum_format=rgba32f --quiet "
                    "--out w.png --report w.json"),
            "wboit with an rgba32f accumulation target");
  j = nlohmann::json::parse(slurp(box.work() / "w.json"));
  EXPECT_EQ(j["render_targets"]["accum"], "rgba32f");
  expect_ok(box.run("run --scene eight-layers --spp 4 --method enderton+depth --enderton-selection original --quiet "
                    "--out e.png --report e.json"),
            "enderton+depth, original selection");
  j = nlohmann::json::parse(slurp(box.work() / "e.json"));
  EXPECT_EQ(j["enderton_selection"], "original");
  EXPECT_EQ(j["passes"], nlohmann::json::array({"stochastic", "accumulate"}));
  expect_ok(box.run("run --fidelity cycle --scene eight-layers --spp 4 --method lk+depth+ac --quiet --out c.png "
                    "--report c.json"),
            "cycle lk+depth+ac");
  j = nlohmann::json::parse(slurp(box.work() / "c.json"));
  ASSERT_EQ(j["timing"]["passes"].size(), 3u);
  EXPECT_GT(j["timing"]["passes"][0]["dram"]["transmittance"]["bytes_written"].get<uint64_t>() +
                j["timing"]["cache"]["transmittance"]["write_hits"].get<uint64_t>() +
                j["timing"]["cache"]["transmittance"]["write_misses"].get<uint64_t>(),
            0u);
  expect_cli_error(box, "run --scene testcard --spp 1 --method wboit --hw-set blend.samples_per_clock=8",
                   {"--hw-set", "cycle"});
  expect_cli_error(box, "run --scene testcard --spp 1 --method lk --enderton-selection sideways",
                   {"--enderton-selection"});
  // A multi-pass method's waveform: each pass under its own scope.
  expect_ok(box.run("run --fidelity cycle --scene testcard --spp 1 --method lk+depth --quiet --vcd w.vcd"),
            "--vcd of a two-pass method");
  const ropsim_test::Vcd w = ropsim_test::parse_vcd(slurp(box.path("w.vcd")));
  EXPECT_GE(w.find("top.stochastic.rop0", "depth_test"), 0) << "the first pass has no scope";
  EXPECT_GE(w.find("top.accumulate.rop0", "blend"), 0) << "the second pass has no scope";
}

// --fidelity approximate writes the golden image bit for bit and the cycle
// report's timing keys with the bounds it computed; flags that do not apply
// to it, and the reference method, are refused in one line.
TEST(CliApproximate, WritesTheGoldenImageAndTheCycleReportsKeys) {
  CliSandbox box;
  expect_ok(box.run("run --scene cloth --spp 16 --quiet --out f.exr --out f.png --report f.json"), "functional");
  const CliResult r = box.run("run --fidelity approximate --hw '" ROPSIM_SOURCE_DIR
                              "/configs/narrow.toml' --scene cloth --spp 16 --out a.exr --out a.png --report a.json");
  expect_ok(r, "approximate");
  EXPECT_NE(r.out.find("approximate model"), std::string::npos) << "the summary line\n" << r.describe();
  EXPECT_EQ(slurp(box.work() / "f.exr"), slurp(box.work() / "a.exr")) << "the approximate run writes the golden image";
  EXPECT_EQ(slurp(box.work() / "f.png"), slurp(box.work() / "a.png"));
  const auto f = nlohmann::json::parse(slurp(box.work() / "f.json"));
  const auto a = nlohmann::json::parse(slurp(box.work() / "a.json"));
  EXPECT_EQ(a["fidelity"], "approximate");
  EXPECT_EQ(a["counters"], f["counters"]) << "the golden model's counters, exactly";
  const auto& t = a["timing"];
  EXPECT_GT(t["total_cycles"].get<uint64_t>(), 0u);
  EXPECT_GT(t["dram"]["bytes_read"].get<uint64_t>(), 0u);
  EXPECT_GT(t["dram"]["bytes_written"].get<uint64_t>(), 0u);
  EXPECT_TRUE(t["bottleneck"].is_string());
  for (const char* b : {"source", "distributor", "unit", "latency", "scoreboard", "dram"})
    EXPECT_TRUE(t["approximate"]["bound_cycles"].contains(b)) << b;
  EXPECT_EQ(a["hardware"]["resolved"]["distributor"]["rop_units"], 1) << "the design given";
  expect_cli_error(box, "run --fidelity approximate --scene testcard --spp 1 --vcd w.vcd", {"--vcd", "approximate"});
  expect_cli_error(box, "run --fidelity approximate --scene testcard --spp 1 --stats-interval 10 --stats-csv s.csv",
                   {"--stats-interval", "approximate"});
  expect_cli_error(box, "run --fidelity approximate --scene testcard --spp 1 --sample-units 3",
                   {"--sample-units", "sampled"});
  expect_cli_error(box, "run --fidelity approximate --scene testcard --spp 1 --method reference", {"reference"});
  expect_cli_error(box, "run --fidelity approximate --scene testcard --spp 1 --hw-set cache.ways=3", {"cache.ways"});
}
