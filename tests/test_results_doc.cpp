// docs/results.md's deterministic tables are what the code gives:
// scripts/results.py regenerates every fast table (built-in scenes, seconds)
// and diffs it against the committed text; and the check does fail when a
// committed figure is edited by hand.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "tests/study_test_util.h"

namespace {

using namespace ropsim_test;
namespace fs = std::filesystem;

const fs::path kSource = ROPSIM_SOURCE_DIR;
const std::string kPython = "/usr/bin/python3";

std::string results_py(const std::string& args) {
  return kPython + " '" + (kSource / "scripts" / "results.py").string() + "' --ropsim '" ROPSIM_BINARY "' " + args;
}

/// The fast tables' names, as `results.py --list` prints them ("NAME fast").
std::vector<std::string> fast_tables(const fs::path& dir) {
  const Ran r = shell(dir, results_py("--list"), 60);
  std::vector<std::string> names;
  std::istringstream in(r.out);
  std::string name, speed;
  while (in >> name >> speed)
    if (speed == "fast") names.push_back(name);
  return names;
}

TEST(ResultsDoc, EveryFastFigureRegenerates) {
  if (!fs::exists(kPython)) GTEST_SKIP() << kPython << " is absent (scripts/results.py needs Debian's python3)";
  Scratch scratch("ropsim-test-results-doc");
  const Ran r = shell(scratch.dir, results_py("--check --fast"), 600);
  EXPECT_EQ(r.status, 0) << "a table of docs/results.md is not what the code gives (status " << r.status
                         << "); if the code is right, rewrite it with scripts/results.py --write --only NAME and "
                            "commit the doc. The diff (committed -> generated):\n"
                         << r.out << r.err;
}

TEST(ResultsDoc, TheCheckFailsWhenAFigureIsEditedByHand) {
  if (!fs::exists(kPython)) GTEST_SKIP() << kPython << " is absent (scripts/results.py needs Debian's python3)";
  Scratch scratch("ropsim-test-results-doc-edit");
  const std::vector<std::string> fast = fast_tables(scratch.dir);
  ASSERT_FALSE(fast.empty()) << "scripts/results.py --list names no fast table";
  std::string doc = slurp(kSource / "docs" / "results.md");

  // The first fast table in the doc, its first data row (after the header and
  // the |---| line), the last digit of its second cell: one figure, changed.
  std::string name;
  size_t open = std::string::npos;
  for (const std::string& n : fast) {
    const size_t at = doc.find("<!-- results:" + n + " -->\n");
    if (at != std::string::npos && (open == std::string::npos || at < open)) open = at, name = n;
  }
  ASSERT_NE(open, std::string::npos) << "docs/results.md holds no block of a fast table (" << fast.front() << ", ...)";
  size_t row = open;
  for (int i = 0; i < 3; ++i) row = doc.find('\n', row) + 1;  // marker, header, |---| -> first data row
  const size_t cell = doc.find('|', doc.find('|', row) + 1);  // the second cell's opening bar
  const size_t cell_end = doc.find('|', cell + 1);
  size_t digit = std::string::npos;
  for (size_t i = cell + 1; i < cell_end; ++i)
    if (doc[i] >= '0' && doc[i] <= '9') digit = i;
  ASSERT_NE(digit, std::string::npos) << "table " << name << ": the second cell of its first row holds no digit: "
                                      << doc.substr(row, doc.find('\n', row) - row);
  doc[digit] = static_cast<char>('0' + (doc[digit] - '0' + 1) % 10);
  const fs::path copy = scratch.dir / "results.md";
  std::ofstream(copy) << doc;

  const Ran r = shell(scratch.dir, results_py("--check --fast --only " + name + " --doc '" + copy.string() + "'"), 600);
  EXPECT_EQ(r.status, 1) << "the check passed (or failed otherwise) although a figure of table " << name
                         << " was changed by hand:\n"
                         << r.out << r.err;
  EXPECT_NE(r.out.find("table " + name), std::string::npos)
      << "the check's diff does not name the edited table " << name << ":\n"
      << r.out << r.err;
  EXPECT_NE(r.out.find("\n-"), std::string::npos) << "the check printed no unified diff:\n" << r.out << r.err;
}

}  // namespace
