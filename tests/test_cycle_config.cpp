// The hardware config: design files and overrides, their errors, the design's
// digest and the resolved TOML; and the report's fields, documented in
// docs/reports.md from their declarations.
#include "tests/cycle_test_util.h"

using namespace ropsim;
using namespace cycle_test;

// ------------------------------------------------------------ config

namespace {
std::string write_tmp(const std::string& name, const std::string& text) {
  const std::string p = ::testing::TempDir() + "/" + name;
  std::ofstream(p) << text;
  return p;
}
void expect_config_error(const std::string& text, const std::string& must_name) {
  const std::string p = write_tmp("bad.toml", text);
  try {
    load_hw_config(p);
    ADD_FAILURE() << "accepted: " << text;
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find(must_name), std::string::npos) << e.what() << " should name " << must_name;
    EXPECT_NE(std::string(e.what()).find(p), std::string::npos) << e.what() << " should name the file";
  }
}
}  // namespace

TEST(HwConfigFile, BadKeysAndValuesNameTheKey) {
  expect_config_error("[dram]\nchanel = 2\n", "dram.chanel");
  expect_config_error("[drams]\nchannels = 2\n", "drams");
  expect_config_error("[dram]\nchannels = 0\n", "dram.channels");
  expect_config_error("[dram]\nchannels = \"two\"\n", "dram.channels");
  expect_config_error("[cache]\nline_bytes = 48\n", "cache.line_bytes");
  expect_config_error("[sorter]\nkind = \"quick\"\n", "sorter.kind");
  expect_config_error("[clock]\nfrequency_ghz = -1\n", "clock.frequency_ghz");
  expect_config_error("[cache]\nsize_bytes = 256\nways = 8\n", "cache.size_bytes");
  expect_config_error("[dram\nchannels = 2\n", "bad.toml");
  expect_config_error("[cache]\nfast_clear = 1\n", "cache.fast_clear");
  expect_config_error("[numerics]\nhash_bits = 7\n", "numerics.hash_bits");
  expect_config_error("[numerics]\nalpha_bits = 33\n", "numerics.alpha_bits");
  expect_config_error("[numerics]\nsurface_id_bits = 1.5\n", "numerics.surface_id_bits");
}

TEST(HwConfigFile, CommittedConfigsLoadAndDifferAndDocsListEveryKey) {
  const auto files = config_files();
  ASSERT_GE(files.size(), 3u) << "configs/ needs a default and at least two contrasting designs";
  std::set<std::string> texts;
  for (const auto& f : files) texts.insert(hw_config_to_toml(load_hw_config(f)));
  EXPECT_EQ(texts.size(), files.size()) << "two configs resolve to the same design";
  std::ifstream doc(kSource + "/docs/config.md");
  std::stringstream ss;
  ss << doc.rdbuf();
  for (const auto& p : hw_params())
    EXPECT_NE(ss.str().find("`" + p.key + "`"), std::string::npos) << "docs/config.md does not document " << p.key;
  // The default file is the built-in defaults.
  EXPECT_EQ(hw_config_to_toml(load_hw_config(kSource + "/configs/default.toml")), hw_config_to_toml(HwConfig{}));
}

// The design's digest (default output names) is a fixed function of the
// resolved values: the same on every machine, different for another design.
// FNV-1a 64 of the built-in defaults (a change of any default or key changes it).
constexpr uint64_t kDefaultDesignDigest = 0xa02bd6ce42f7b9c2ull;

TEST(HwConfigFile, DigestIsStableAndSeesEveryKey) {
  EXPECT_EQ(hw_digest_hex(HwConfig{}), hw_digest_hex(load_hw_config(kSource + "/configs/default.toml")));
  EXPECT_EQ(hw_config_digest(HwConfig{}), kDefaultDesignDigest) << "the digest of the defaults changed";
  std::set<std::string> seen{hw_digest_hex(HwConfig{})};
  for (const char* a :
       {"numerics.hash_bits=31", "numerics.alpha_bits=31", "numerics.surface_id_bits=31", "dram.channels=3",
        "sorter.kind=rank", "cache.fast_clear=false", "clock.frequency_ghz=1.25", "blend.accum_format=rgba32f",
        "blend.samples_per_clock=8", "compression.depth=false", "compression.color_k=2", "hiz.enable=false"}) {
    HwConfig hw;
    apply_hw_override(hw, a);
    EXPECT_TRUE(seen.insert(hw_digest_hex(hw)).second) << a << " did not change the digest";
  }
  HwConfig named;
  named.name = "another name";
  EXPECT_EQ(hw_digest_hex(named), hw_digest_hex(HwConfig{})) << "only the values count";
}

TEST(HwConfigFile, OverridesParseStrictly) {
  HwConfig hw;
  apply_hw_override(hw, "dram.channels=3");
  EXPECT_EQ(hw.dram.channels, 3u);
  apply_hw_override(hw, "sorter.kind=rank");
  EXPECT_EQ(hw.sorter.kind, SorterKind::kRank);
  for (const char* bad : {"dram.channels", "dram.channels=x", "dram.channels=3x", "nope.key=1", "cache.fast_clear=yes"})
    EXPECT_THROW(apply_hw_override(hw, bad), ConfigError) << bad;
}

namespace {
std::string config_error(const std::function<void()>& f) {
  try {
    f();
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "(accepted)";
}
}  // namespace

// An override is parsed and checked first and applied only when valid: a
// rejected one leaves the config as it was, and its error names it, not the
// config it was applied to.
TEST(HwConfigFile, RejectedOverrideNamesItselfAndChangesNothing) {
  HwConfig hw;
  apply_hw_override(hw, "dram.channels=3");
  const std::string before = hw_config_to_toml(hw);
  for (const std::string bad :
       {"cache.ways=65", "cache.ways=0", "cache.ways=-1", "cache.line_bytes=48", "cache.ways=x", "cache.ways= 4",
        "cache.ways=+4", "cache.ways=4 ", "cache.ways=", "cache.ways=99999999999999999999", "clock.frequency_ghz=nan",
        "clock.frequency_ghz=inf", "clock.frequency_ghz=1e999", "clock.frequency_ghz=0x1p0", "clock.frequency_ghz=0",
        "sorter.kind=quick", "cache.fast_clear=1", "cache.wayz=4", "cache.ways"}) {
    const std::string e = config_error([&] { apply_hw_override(hw, bad); });
    EXPECT_EQ(e.rfind("--hw-set " + bad + ": ", 0), 0u) << bad << " -> " << e;
    EXPECT_EQ(e.find("built-in defaults"), std::string::npos) << e;
    EXPECT_EQ(hw_config_to_toml(hw), before) << bad << " changed the config";
    EXPECT_EQ(hw.overrides, std::vector<std::string>{"dram.channels=3"}) << bad;
  }
  // A valid value for the key that breaks the cache shape: accepted on its own
  // (other overrides may follow), rejected by the check after the last one,
  // which names the override, not the defaults it was applied to.
  apply_hw_override(hw, "cache.ways=3");
  const std::string e = config_error([&] { validate_hw_config(hw); });
  EXPECT_EQ(e.rfind("--hw-set cache.ways=3: ", 0), 0u) << e;
  EXPECT_NE(e.find("power-of-two number of sets"), std::string::npos) << e;
  const std::string r = config_error([] { resolve_hw_config("", {"dram.channels=2", "cache.ways=3"}); });
  EXPECT_EQ(r.rfind("--hw-set cache.ways=3: ", 0), 0u) << "names the override that broke it, only that: " << r;
  const std::string two = config_error([] { resolve_hw_config("", {"cache.line_bytes=256", "dram.row_bytes=128"}); });
  EXPECT_EQ(two.rfind("--hw-set cache.line_bytes=256, --hw-set dram.row_bytes=128: dram.row_bytes 128 is smaller", 0),
            0u)
      << two;
}

// The cache shape (and the other cross-key constraints) is checked once,
// after the design file and every override: overrides valid only together
// are accepted in either order.
TEST(HwConfigFile, CacheShapeIsCheckedAfterAllOverrides) {
  // 64-byte lines: 256 bytes hold one 4-way set, not one 8-way set (the default ways).
  for (const auto& sets : std::vector<std::vector<std::string>>{
           {"cache.size_bytes=256", "cache.ways=4"},
           {"cache.ways=4", "cache.size_bytes=256"},
           {"cache.size_bytes=256", "cache.line_bytes=16", "cache.ways=16"},
           {"cache.line_bytes=4096", "dram.row_bytes=4096", "dram.interleave_bytes=4096"}}) {
    HwConfig hw;
    ASSERT_NO_THROW(hw = resolve_hw_config("", sets)) << sets[0] << " then " << sets[1];
    EXPECT_EQ(hw.name, "built-in defaults with --hw-set");
    EXPECT_EQ(hw.overrides, sets);
  }
  const HwConfig hw = resolve_hw_config("", {"cache.size_bytes=256", "cache.ways=4"});
  EXPECT_EQ(hw.cache.ways, 4u);
  EXPECT_EQ(hw.cache.size_bytes, 256u);
  EXPECT_EQ(resolve_hw_config("", {}).name, "built-in defaults");
  // A design file that is only valid with an override: load_hw_config alone
  // rejects it naming the file, resolve_hw_config with the override accepts it.
  const std::string p = write_tmp("small-cache.toml", "[cache]\nsize_bytes = 256\n");
  const std::string alone = config_error([&] { load_hw_config(p); });
  EXPECT_EQ(alone.rfind(p + ": cache.size_bytes 256 is smaller than one set", 0), 0u) << alone;
  EXPECT_EQ(config_error([&] { resolve_hw_config(p, {}); }), alone);
  const HwConfig fixed = resolve_hw_config(p, {"cache.ways=4"});
  EXPECT_EQ(fixed.cache.size_bytes, 256u);
  EXPECT_EQ(fixed.name, p + " with --hw-set");
  // An override that does not touch the broken keys leaves the blame on the file.
  EXPECT_EQ(config_error([&] { resolve_hw_config(p, {"dram.channels=2"}); }).rfind(p + ": ", 0), 0u);
  // A bad override among good ones names itself.
  EXPECT_EQ(config_error([&] {
              resolve_hw_config(p, {"cache.ways=4", "dram.banks=0"});
            }).rfind("--hw-set dram.banks=0: ", 0),
            0u);
}

// The resolved design (the report's hardware.resolved_toml) prints every
// number so that it reads back as the same value: written out and loaded
// again it is the same design, bit for bit.
TEST(HwConfigFile, ResolvedTomlRoundTripsEveryNumber) {
  for (const char* f : {"1.23456789", "0.30000000000000004", "0.3333333333333333", "2", "9.999999999999998", "0.01",
                        "1.5", "6.02214076", "1e-2", "3.0000000000000004"}) {
    HwConfig hw;
    apply_hw_override(hw, std::string("clock.frequency_ghz=") + f);
    apply_hw_override(hw, "cache.size_bytes=1073741824");
    apply_hw_override(hw, "dram.bytes_per_clock=1048575");
    const std::string toml = hw_config_to_toml(hw);
    const HwConfig back = load_hw_config(write_tmp("resolved.toml", toml));
    EXPECT_EQ(std::memcmp(&back.clock.frequency_ghz, &hw.clock.frequency_ghz, sizeof(double)), 0)
        << f << " read back as " << back.clock.frequency_ghz << " from\n"
        << toml;
    EXPECT_EQ(hw_config_to_toml(back), toml) << f;
  }
  HwConfig hw;
  apply_hw_override(hw, "clock.frequency_ghz=1.23456789");
  EXPECT_NE(hw_config_to_toml(hw).find("frequency_ghz = 1.23456789  #"), std::string::npos) << hw_config_to_toml(hw);
  apply_hw_override(hw, "clock.frequency_ghz=2");
  EXPECT_NE(hw_config_to_toml(hw).find("frequency_ghz = 2.0  #"), std::string::npos) << "a TOML float, not an integer";
}

// ------------------------------------------------------------ report fields

namespace {

/// Every leaf field of a report as a path: objects by ".", array elements as
/// "[]". An empty array has no field (e.g. slab's compressed surfaces: none).
void leaf_paths(const nlohmann::ordered_json& j, const std::string& at, std::set<std::string>& out) {
  if (j.is_object()) {
    for (auto it = j.begin(); it != j.end(); ++it)
      leaf_paths(it.value(), at.empty() ? it.key() : at + "." + it.key(), out);
  } else if (j.is_array() && j.empty()) {
    return;
  } else if (j.is_array() && j[0].is_object()) {
    for (const auto& e : j) leaf_paths(e, at + "[]", out);
  } else {
    out.insert(at);
  }
}

std::string generated_section(const std::string& doc) {
  const std::string begin = "<!-- report fields: generated by `ropsim report-fields --markdown` -->\n";
  const std::string end = "<!-- end of report fields -->";
  const size_t a = doc.find(begin), b = doc.find(end);
  if (a == std::string::npos || b == std::string::npos || b < a) return "(markers missing)";
  return doc.substr(a + begin.size(), b - a - begin.size());
}

}  // namespace

// Every field of a report is written with its unit and meaning (report_fields.h);
// docs/reports.md is generated from those declarations and must equal them,
// and a real report of every method has no field they do not describe.
TEST(ReportFields, DocsAreGeneratedFromTheDeclarationsAndCoverEveryReport) {
  const auto docs = report_field_docs();
  std::set<std::string> described;
  for (const auto& d : docs) {
    EXPECT_TRUE(described.insert(d.path).second) << d.path << " is described twice";
    EXPECT_FALSE(d.unit.empty()) << d.path << " has no unit";
    EXPECT_FALSE(d.meaning.empty()) << d.path << " has no meaning";
  }
  std::ifstream f(kSource + "/docs/reports.md");
  std::stringstream ss;
  ss << f.rdbuf();
  const std::string want = fields_markdown(docs);
  EXPECT_EQ(generated_section(ss.str()), want)
      << "docs/reports.md is out of date: regenerate its table with `ropsim report-fields --markdown`";

  for (Method m :
       {Method::kLk, Method::kEnderton, Method::kNaive, Method::kA2c, Method::kOpaque, Method::kHashed,
        Method::kHashedA2c, Method::kSlab, Method::kWboit, Method::kLkAc, Method::kEndertonDepth, Method::kLkDepthAc}) {
    InputSpec in = scene_input("smoke", 4);
    ReportContext ctx;
    ctx.input = in;
    ctx.config = method_config(m);
    const CycleRun c = run_cycle(in, ctx.config, HwConfig{});
    std::set<std::string> leaves;
    leaf_paths(cycle_report(ctx, c, std::nullopt), "", leaves);
    for (const auto& p : leaves)
      EXPECT_TRUE(described.count(p)) << to_string(m) << ": report field " << p << " is not described";
    EXPECT_TRUE(leaves.count("timing.units[].cycles.busy")) << "the scan of the report is broken";
  }
}
