// The TOML guard (util/toml_guard.h): toml++ 3.3.0's undefined behaviour
// (marzer/tomlplusplus#190) is never reached. Inputs that would reach it are
// refused with their line and column; UTF-8 in strings and comments, where
// TOML allows it, still parses. Under the sanitizer build (UBSan's
// -fsanitize=unreachable) the accepted inputs also show toml++ stays defined.
#include <gtest/gtest.h>
#include <toml++/toml.h>

#include <string>

#include "study_test_util.h"
#include "toml_guard.h"

namespace {

using namespace ropsim_test;

struct Refused {
  const char* text;
  size_t line, column;
};

TEST(TomlGuard, RefusesEveryPlaceToml330TestsANonAsciiCharacterForWhitespace) {
  const Refused cases[] = {
      {"s = \"\"\"\\\n\xc2\xa7\"\"\"\n", 2, 1},            // the upstream report: line-ending backslash, then U+00A7
      {"s = \"\"\"\\   \n   \n  \xc3\xa9\"\"\"\n", 3, 3},  // blanks and empty lines between
      {"s = \"\"\"a\\  \xc3\xa9\"\"\"\n", 1, 12},          // backslash, blanks, then non-ASCII on the same line
      {"\xc2\xa7 = 1\n", 1, 1},                            // a line starting with it
      {"a = 1\n\xd0\xba\xd0\xbb = 2\n", 2, 1},             // a non-ASCII bare key
      {"a = 1\xc2\xa7\n", 1, 6},                           // after a value
      {"a =\xc2\xa0 1\n", 1, 4},                           // as whitespace (U+00A0)
      {"s = \"x\\\xc3\xa9\"\n", 1, 8},                     // after a backslash in a basic string
      {"[t\xc3\xa9]\n", 1, 3},                             // in a table header
      {"s =5\"\xc2\xa7\"\n", 1, 6},                        // a quote where no string starts (found by fuzzing)
      {"a = 1 'x\xc3\xa9'\n", 1, 9},
  };
  for (const auto& c : cases) {
    const ropsim::TomlGuardProblem p = ropsim::toml_guard(c.text);
    EXPECT_TRUE(p) << "accepted: " << c.text;
    EXPECT_EQ(p.line, c.line) << c.text;
    EXPECT_EQ(p.column, c.column) << c.text;
  }
  EXPECT_EQ(ropsim::toml_guard_message("a = 1\n\xc2\xa7 = 2\n", "cfg.toml").rfind("cfg.toml:2:1: non-ASCII", 0), 0u)
      << ropsim::toml_guard_message("a = 1\n\xc2\xa7 = 2\n", "cfg.toml");
}

TEST(TomlGuard, KeepsUtf8InStringsAndCommentsWorking) {
  const char* ok[] = {
      "name = \"K\xc3\xbche\"\n",
      "# Gr\xc3\xbc\xc3\x9f\x65\nname = 'x'\n",  // \x65: 'e', not part of the escape before
      "a = 1 # \xc2\xa7 trailing\n",
      "\"\xd0\xba\xd0\xbb\xd1\x8e\xd1\x87\" = 1\n",  // a quoted key
      "s = '''\n\xc2\xa7'''\n",
      "s = \"\"\"\n\xc2\xa7 starts a line inside the string\"\"\"\n",
      "s = \"\"\"\\\n  x\xc2\xa7\"\"\"\n",
      "s = \"\"\"a\"\"\"\"\n",  // a string ending in a quote
      "s = \"\\\\\"\nt = \"\xc3\xa9\"\n",
      "a = [\"\xc3\xa9\", '\xc3\xa9'] # \xc3\xa9\n",
  };
  for (const char* t : ok) {
    EXPECT_FALSE(ropsim::toml_guard(t)) << "refused: " << t << " (" << ropsim::toml_guard(t).what << ")";
    try {
      (void)toml::parse(std::string_view(t), std::string_view("ok.toml"));
    } catch (const toml::parse_error& e) {
      ADD_FAILURE() << "the test input is not TOML: " << t << ": " << e.description();
    }
  }
}

TEST(TomlGuard, EveryTomlInputRefusesTheTriggerWithOneLineNamingFileAndLine) {
  Scratch s("toml-guard");
  const std::string trigger = "# ok\n\xc2\xa7 = 1\n";
  s.put("design.toml", trigger);
  s.put("scene.toml", trigger);
  s.put("study.toml", trigger);
  const std::string cmds[] = {
      "run --scene cloth --spp 4 --fidelity cycle --hw design.toml --quiet --out o.png --report r.json",
      "capture scene.toml -o t.rtrace",
      "study run study.toml --out st",
  };
  const char* files[] = {"design.toml", "scene.toml", "study.toml"};
  for (int k = 0; k < 3; ++k) {
    const Ran r = ropsim_test::ropsim(s.dir, cmds[k], 120);
    EXPECT_EQ(r.status, 1) << cmds[k] << "\n" << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << cmds[k] << ": not one line:\n" << r.err;
    EXPECT_NE(r.err.find(std::string(files[k]) + ":2:1: non-ASCII"), std::string::npos) << cmds[k] << "\n" << r.err;
  }
  EXPECT_FALSE(fs::exists(s.dir / "o.png"));
  EXPECT_FALSE(fs::exists(s.dir / "t.rtrace"));
  EXPECT_FALSE(fs::exists(s.dir / "st"));
}

}  // namespace
