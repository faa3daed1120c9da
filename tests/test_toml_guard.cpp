// The TOML guard (util/toml_guard.h): toml++ 3.3.0's undefined behaviour
// (marzer/tomlplusplus#190) is never reached because the parser is given only
// ASCII. Non-ASCII where TOML forbids it and malformed UTF-8 are refused with
// their line and column; UTF-8 in strings and comments, where TOML allows it,
// parses to the same values. Under the sanitizer build (UBSan's
// -fsanitize=unreachable) every parse here also shows toml++ stays defined.
#include <gtest/gtest.h>
#include <toml++/toml.h>

#include <algorithm>
#include <random>
#include <string>

#include "tests/study_test_util.h"
#include "util/toml_guard.h"

namespace {

using namespace ropsim_test;

struct Refused {
  const char* text;
  size_t line, column;
};

TEST(TomlGuard, RefusesNonAsciiWhereTomlForbidsItAndMalformedUtf8) {
  const Refused cases[] = {
      {"\xc2\xa7 = 1\n", 1, 1},                 // a line starting with it
      {"a = 1\n\xd0\xba\xd0\xbb = 2\n", 2, 1},  // a non-ASCII bare key
      {"a = 1\xc2\xa7\n", 1, 6},                // after a value
      {"a =\xc2\xa0 1\n", 1, 4},                // as whitespace (U+00A0)
      {"s = \"x\\\xc3\xa9\"\n", 1, 8},          // after a backslash in a basic string
      {"[t\xc3\xa9]\n", 1, 3},                  // in a table header
      {"s = \"\xc3\"\n", 1, 6},                 // a truncated sequence in a string
      {"s = \"\xc0\xaf\"\n", 1, 6},             // overlong
      {"s = '\xed\xa0\x80'\n", 1, 6},           // a surrogate, in a literal string
      {"# \xf4\x90\x80\x80\n", 1, 3},           // beyond U+10FFFF, in a comment
      {"s = \"\"\"\n\n\x80\"\"\"\n", 3, 1},     // a stray continuation byte
  };
  for (const auto& c : cases) {
    const ropsim::TomlGuardProblem p = ropsim::toml_guard(c.text);
    EXPECT_TRUE(p) << "accepted: " << c.text;
    EXPECT_EQ(p.line, c.line) << c.text;
    EXPECT_EQ(p.column, c.column) << c.text;
  }
  const ropsim::TomlInput in = ropsim::toml_input("a = 1\n\xc2\xa7 = 2\n", "cfg.toml");
  EXPECT_EQ(in.error.rfind("cfg.toml:2:1: non-ASCII", 0), 0u) << in.error;
  EXPECT_TRUE(in.ascii.empty());
}

struct Kept {
  const char* text;
  const char* key;
  const char* value;  ///< the string value the parser must read for key
};

TEST(TomlGuard, UnicodeInStringsAndCommentsReadsAsTheSameValues) {
  const Kept cases[] = {
      {"name = \"K\xc3\xbche\"\n", "name", "K\xc3\xbche"},
      {"# Gr\xc3\xbc\xc3\x9f\x65\nname = 'x'\n", "name", "x"},
      {"a = 'y' # \xc2\xa7 trailing\n", "a", "y"},
      {"\"\xd0\xba\xd0\xbb\xd1\x8e\xd1\x87\" = 'k'\n", "\xd0\xba\xd0\xbb\xd1\x8e\xd1\x87", "k"},  // a quoted key
      {"s = '''\n\xc2\xa7'''\n", "s", "\xc2\xa7"},  // first newline trimmed
      {"s = \"\"\"\n\xc2\xa7 starts a line\"\"\"\n", "s", "\xc2\xa7 starts a line"},
      {"s = \"\"\"\\\n\xc2\xa7\"\"\"\n", "s", "\xc2\xa7"},  // the upstream report: line-ending backslash, then U+00A7
      {"s = \"\"\"a\\  \n   \n  \xc3\xa9\"\"\"\n", "s", "a\xc3\xa9"},            // blanks and empty lines between
      {"s = \"\"\"a\"\"\"\"\n", "s", "a\""},                                     // a string ending in a quote
      {"s = \"\xf0\x9f\x98\x80 \\u00e9\"\n", "s", "\xf0\x9f\x98\x80 \xc3\xa9"},  // beyond the BMP, beside an escape
      {"p = 'C:\\dir\\\xc3\xa9\"x'\n", "p", "C:\\dir\\\xc3\xa9\"x"},        // a literal: backslashes and quotes kept
      {"p = '''a\\\n\"b\" \xc3\xa9'''''\n", "p", "a\\\n\"b\" \xc3\xa9''"},  // a multi-line literal ending in quotes
      {"\xef\xbb\xbfs = \"\xc3\xa9\"\n", "s", "\xc3\xa9"},                  // a byte order mark
  };
  for (const auto& c : cases) {
    const ropsim::TomlInput in = ropsim::toml_input(c.text, "ok.toml");
    ASSERT_EQ(in.error, "") << c.text;
    EXPECT_TRUE(std::all_of(in.ascii.begin(), in.ascii.end(), [](char ch) { return (ch & 0x80) == 0; })) << in.ascii;
    EXPECT_EQ(std::count(in.ascii.begin(), in.ascii.end(), '\n'), std::count(c.text, c.text + strlen(c.text), '\n'))
        << "lines moved: " << in.ascii;
    try {
      const toml::table t = toml::parse(std::string_view(in.ascii), std::string_view("ok.toml"));
      EXPECT_EQ(t[c.key].value_or(std::string("<missing>")), std::string(c.value)) << c.text << "\nas " << in.ascii;
    } catch (const toml::parse_error& e) {
      ADD_FAILURE() << c.text << "\nas " << in.ascii << ": " << e.description();
    }
  }
}

// The property the parser's safety rests on: whatever the bytes, the guard
// either refuses them or hands on pure ASCII with the same line count. Random
// texts (fixed seed) from an alphabet of TOML's structural characters and
// multi-byte sequences, valid and not, in every mix.
TEST(TomlGuard, AnyInputBecomesPureAsciiOrIsRefused) {
  const std::string pieces[] = {"\"",
                                "\"\"\"",
                                "'",
                                "'''",
                                "\\",
                                "#",
                                "\n",
                                "\r\n",
                                " ",
                                "=",
                                "[",
                                "]",
                                "{",
                                "}",
                                ",",
                                ".",
                                "a",
                                "1",
                                "+",
                                "\xc2\xa7",
                                "\xc2\xa0",
                                "\xe3\x80\x80",
                                "\xf0\x9f\x98\x80",
                                "\xc3",
                                "\x80",
                                "\xef\xbb\xbf",
                                "\\u00e9",
                                "\t"};
  std::mt19937 rng(20261201);
  std::uniform_int_distribution<size_t> pick(0, std::size(pieces) - 1), len(0, 40);
  int refused = 0, accepted = 0;
  for (int n = 0; n < 20000; ++n) {
    std::string text;
    for (size_t k = len(rng); k > 0; --k) text += pieces[pick(rng)];
    std::string ascii;
    if (ropsim::toml_guard(text, &ascii)) {
      ++refused;
      continue;
    }
    ++accepted;
    ASSERT_TRUE(std::all_of(ascii.begin(), ascii.end(), [](char ch) { return (ch & 0x80) == 0; }))
        << "non-ASCII handed on for: " << text;
    ASSERT_EQ(std::count(ascii.begin(), ascii.end(), '\n'), std::count(text.begin(), text.end(), '\n')) << text;
    try {
      (void)toml::parse(std::string_view(ascii), std::string_view("random.toml"));
    } catch (const toml::parse_error&) {
    }
  }
  // Both sides were exercised (the alphabet makes either common).
  EXPECT_GT(refused, 1000);
  EXPECT_GT(accepted, 1000);
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

// A design whose strings hold UTF-8 where the file allows it loads; a comment
// in any language is fine.
TEST(TomlGuard, ADesignWithUnicodeCommentsLoads) {
  Scratch s("toml-guard-ok");
  s.put("design.toml",
        "# Entwurf f\xc3\xbcr 8 ROPs \xe2\x80\x94 gro\xc3\x9f\n[distributor]\nrop_units = 8 # \xc2\xa7\n");
  const Ran r = ropsim_test::ropsim(s.dir, "config design.toml --json", 60);
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("\"rop_units\": 8"), std::string::npos) << r.out;
}

}  // namespace
