// Application entries (traces/apps/*.toml, app_entry.h): what a file says,
// what overrides change, and a one-line error naming the file, line and key
// for every bad entry. No GL here; test_capture_gl.cpp captures the entries.
#include <gtest/gtest.h>

#include <filesystem>
#include <set>
#include <string>

#include "traces/capture/app_entry.h"
#include "traces/capture/scene_file.h"

namespace fs = std::filesystem;
using ropsim::AppEntry;
using ropsim::AppOverrides;
using ropsim::CaptureError;
using ropsim::parse_app_entry;

namespace {

const char* kEntry = R"(# a comment
[app]
name = "demo"
package = "glmark2-x11"
command = ["glmark2", "--size", "{width}x{height}", "-b", "jellyfish:duration=1"]
frame = 3
target = "fbo:2"
width = 128
height = 96
spp = 4
timeout = 30
shows = "a jellyfish"
)";

/// The message of the CaptureError that parsing text throws ("" if none).
std::string error_of(const std::string& text, const AppOverrides& o = {}) {
  try {
    parse_app_entry(text, "e.toml", o);
  } catch (const CaptureError& e) {
    return e.what();
  }
  return "";
}

std::string with(const std::string& from, const std::string& to) {
  std::string s = kEntry;
  const size_t at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return at == std::string::npos ? s : s.replace(at, from.size(), to);
}

}  // namespace

TEST(AppEntry, AnEntryGivesItsCommandFrameTargetSizeAndSpp) {
  const AppEntry e = parse_app_entry(kEntry, "dir/e.toml");
  EXPECT_EQ(e.name, "demo");
  EXPECT_EQ(e.package, "glmark2-x11");
  EXPECT_EQ(e.frame, 3);
  EXPECT_EQ(e.target, "fbo:2");
  EXPECT_EQ(e.width, 128u);
  EXPECT_EQ(e.height, 96u);
  EXPECT_EQ(e.spp, 4);
  EXPECT_DOUBLE_EQ(e.timeout, 30.0);
  EXPECT_FALSE(e.large);
  EXPECT_EQ(e.shows, "a jellyfish");
  const std::vector<std::string> argv = ropsim::app_command(e);
  ASSERT_EQ(argv.size(), 5u);
  EXPECT_EQ(argv[2], "128x96") << "{width} and {height} are the capture's size";
}

TEST(AppEntry, OverridesChangeTheSizeSppAndFrameAndTheCommandFollows) {
  AppOverrides o;
  o.spp = 16;
  o.width = 64;
  o.height = 48;
  o.frame = 7;
  const AppEntry e = parse_app_entry(kEntry, "e.toml", o);
  EXPECT_EQ(e.spp, 16);
  EXPECT_EQ(e.frame, 7);
  EXPECT_EQ(ropsim::app_command(e)[2], "64x48");
  o = {};
  o.spp = 3;
  EXPECT_NE(error_of(kEntry, o).find("spp 3"), std::string::npos) << error_of(kEntry, o);
}

TEST(AppEntry, TheNameDefaultsToTheFilesStemAndOptionalKeysToTheirDefaults) {
  std::string s = kEntry;
  for (const char* line : {"name = \"demo\"\n", "target = \"fbo:2\"\n", "spp = 4\n", "timeout = 30\n"})
    s.erase(s.find(line), std::string(line).size());
  const AppEntry e = parse_app_entry(s, "apps/glmark2-demo.toml");
  EXPECT_EQ(e.name, "glmark2-demo");
  EXPECT_EQ(e.target, "presented");
  EXPECT_EQ(e.spp, 1);
  EXPECT_DOUBLE_EQ(e.timeout, 120.0);
}

TEST(AppEntry, EveryBadEntryIsOneLineNamingTheFileLineAndKey) {
  struct Case {
    std::string text, needle;
  };
  std::string no_package = kEntry;
  no_package.erase(no_package.find("package"),
                   no_package.find('\n', no_package.find("package")) - no_package.find("package") + 1);
  const std::vector<Case> cases = {
      {"name = 1\n", "app: missing"},
      {with("spp = 4", "spp = 5"), "e.toml:10: app.spp: must be 1, 2, 4, 8, 16, 32 or 64"},
      {with("frame = 3", "frame = -1"), "e.toml:6: app.frame: must be >= 0"},
      {with("target = \"fbo:2\"", "target = \"fbo:0\""), "app.target: \"fbo:0\" is not presented or fbo:N"},
      {with("width = 128", "width = 8"), "app.width: must be in 16..16384"},
      {with("command = [\"glmark2\"", "command = [\"\""), "app.command: the program"},
      {with("command = [\"glmark2\", \"--size\", \"{width}x{height}\", \"-b\", \"jellyfish:duration=1\"]",
            "command = []"),
       "app.command: must not be empty"},
      {with("command = [\"glmark2\"", "command = [1"), "app.command: must be an array of strings"},
      {with("shows = \"a jellyfish\"", "shows = \"x\"\ncolour = 1"), "e.toml:13: app.colour: unknown key"},
      {with("[app]", "[app]\n[other]"), "other: unknown key"},
      {no_package, "app.package: missing (required)"},
      {with("package = \"glmark2-x11\"", "package = \"a b\""), "app.package: must be one Debian package name"},
      {with("frame = 3", "frame = 3\nframe = 4"), "e.toml:7"},
  };
  for (const Case& c : cases) {
    const std::string msg = error_of(c.text);
    EXPECT_NE(msg.find(c.needle), std::string::npos) << "expected \"" << c.needle << "\" in \"" << msg << "\"";
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    EXPECT_EQ(msg.rfind("e.toml", 0), 0u) << "the message names the file first: " << msg;
  }
}

// Every entry of the suite reads, names a Debian package and a command, says
// what it shows, and has a name of its own.
TEST(AppEntry, TheSuitesEntriesAreValid) {
  const fs::path dir = fs::path(ROPSIM_SOURCE_DIR) / "traces" / "apps";
  std::set<std::string> names;
  size_t n = 0;
  for (const auto& f : fs::directory_iterator(dir)) {
    if (f.path().extension() != ".toml") continue;
    SCOPED_TRACE(f.path().string());
    const AppEntry e = ropsim::load_app_entry(f.path().string());
    EXPECT_FALSE(e.package.empty());
    EXPECT_FALSE(e.shows.empty());
    EXPECT_TRUE(names.insert(e.name).second) << "two entries are named " << e.name;
    ++n;
  }
  EXPECT_GE(n, 4u) << "the suite holds glmark2's blending scenes and an opaque control";
}
