// `ropsim study report` (docs/studies.md "The report"), through the real
// ropsim binary and a real headless Chromium: the report of a small study is
// written (index.html and summary.md), references no external resource, and
// renders in the browser with its headings, every image decoded and no failed
// resource load; a study with a failed point and only functional points still
// gives a report that renders; a folder that is not a study is a one-line
// error.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "study_test_util.h"

namespace fs = std::filesystem;

namespace {

using namespace ropsim_test;

/// A scratch folder named for this suite.
struct ReportScratch : Scratch {
  ReportScratch() : Scratch("ropsim-test-study-report") {}
};

size_t count(const std::string& s, const std::string& what) {
  size_t n = 0;
  for (size_t at = s.find(what); at != std::string::npos; at = s.find(what, at + what.size())) ++n;
  return n;
}

/// The src= and href= values of a page that are not data: URIs (an
/// external resource: http, file, or a relative path).
std::vector<std::string> external_refs(const std::string& page) {
  // A plain scan: std::regex overflows the stack on the long data URIs.
  std::string lower(page.size(), ' ');
  std::transform(page.begin(), page.end(), lower.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  std::vector<std::string> bad;
  for (const std::string attr : {"src=", "href="})
    for (size_t at = lower.find(attr); at != std::string::npos; at = lower.find(attr, at + 1)) {
      if (at > 0 && (std::isalnum(static_cast<unsigned char>(lower[at - 1])) || lower[at - 1] == '-')) continue;
      size_t v = at + attr.size();
      if (v < lower.size() && (lower[v] == '"' || lower[v] == '\'')) ++v;
      if (lower.compare(v, 5, "data:") != 0) bad.push_back(page.substr(at, 60));
    }
  if (lower.find("url(") != std::string::npos) bad.push_back("a CSS url(...)");
  if (lower.find("@import") != std::string::npos) bad.push_back("a CSS @import");
  return bad;
}

/// Opens a page in headless Chromium (bounded by a timeout) and returns the
/// DOM after the load event and the browser's log.
struct Rendered {
  int status;
  std::string dom, log;
};
Rendered render(const fs::path& work, const fs::path& page) {
  // As root Chromium needs --no-sandbox; a fresh profile per run keeps
  // concurrent tests apart. The DOM is dumped after the load event.
  const fs::path profile = work / ".chromium-profile";
  const Ran r = shell(work,
                      "timeout 120 chromium --headless --no-sandbox --disable-gpu --no-first-run "
                      "--disable-extensions --user-data-dir='" +
                          profile.string() + "' --enable-logging=stderr --v=0 --dump-dom 'file://" +
                          fs::absolute(page).string() + "'");
  return Rendered{r.status, r.out, r.err};
}

bool have_chromium() { return std::system("command -v chromium >/dev/null 2>&1") == 0; }

/// Checks the report under study_dir/report: both files, no external
/// resource, and in the browser the headings, `images` images all decoded and
/// no failed resource load. Returns the HTML.
std::string check_report(const fs::path& work, const fs::path& study_dir, size_t images,
                         const std::vector<std::string>& headings) {
  const fs::path html = study_dir / "report" / "index.html", md = study_dir / "report" / "summary.md";
  EXPECT_TRUE(fs::is_regular_file(html));
  EXPECT_TRUE(fs::is_regular_file(md));
  const std::string page = slurp(html), summary = slurp(md);
  EXPECT_TRUE(external_refs(page).empty()) << "external resource: " << external_refs(page).front();
  EXPECT_EQ(count(page, "<img"), images) << "images in the HTML";
  EXPECT_EQ(count(page, "src=\"data:image/png;base64,"), images) << "every image is a data URI";
  for (const auto& h : headings) {
    EXPECT_NE(page.find(">" + h + "</h"), std::string::npos) << "heading " << h;
    EXPECT_NE(summary.find("# " + h + "\n"), std::string::npos) << "summary.md heading " << h;
  }
  for (const auto& e : fs::directory_iterator(study_dir / "report"))
    EXPECT_TRUE(e.path().filename() == "index.html" || e.path().filename() == "summary.md")
        << "left behind: " << e.path();

  if (!have_chromium()) {
    ADD_FAILURE() << "chromium is not installed (scripts/deps.sh installs it)";
    return page;
  }
  const Rendered r = render(work, html);
  EXPECT_EQ(r.status, 0) << "chromium failed:\n" << r.log;
  for (const auto& h : headings) EXPECT_NE(r.dom.find(">" + h + "</h"), std::string::npos) << "rendered heading " << h;
  EXPECT_EQ(count(r.dom, "<img"), images) << "images in the rendered DOM";
  EXPECT_NE(r.dom.find("data-images-decoded=\"" + std::to_string(images) + "\""), std::string::npos)
      << "the browser did not decode every image (the page's load handler sets data-images-decoded):\n"
      << r.dom.substr(0, 600);
  EXPECT_EQ(r.log.find("resource failed to load"), std::string::npos) << r.log;
  EXPECT_EQ(r.log.find("net::ERR_"), std::string::npos) << r.log;
  EXPECT_EQ(r.log.find("Uncaught"), std::string::npos) << r.log;
  return page;
}

}  // namespace

TEST(StudyReport, ASmallStudysReportIsSelfContainedAndRendersInChromium) {
  ReportScratch s;
  s.put("small.toml", R"(
[study]
name = "report-small"
save_images = true

[inputs]
scenes = ["cloth", "eight-layers"]

[axes]
method = ["lk", "enderton", "opaque"]
spp = [4, 16]
fidelity = ["functional", "cycle"]
width = 32
height = 32
)");
  const Ran run = ropsim(s.dir, "study run small.toml --out st -j 2 --quiet");
  ASSERT_EQ(run.status, 0) << run.err << run.out;
  const Ran rep = ropsim(s.dir, "study report st");
  ASSERT_EQ(rep.status, 0) << rep.err << rep.out;
  EXPECT_NE(rep.out.find("index.html"), std::string::npos) << rep.out;
  // Figures: RMSE against DRAM bytes, against cycles, against the functional
  // state bytes; lk's RMSE and silicon cost against spp; the key metrics
  // against spp (the one numeric axis with more than one value); bottleneck
  // classes; cycles by activity; one image strip per input.
  const std::string page = check_report(
      s.dir, s.dir / "st", 3 + 1 + 1 + 2 + 2,
      {"Study report-small", "Points", "Failures", "Quality against cost", "Equal quality", "Quality against silicon",
       "Parameters against metrics", "Bottlenecks and stall reasons", "Image strips"});
  EXPECT_NE(page.find("24 points: 24 ok, 0 failed"), std::string::npos);
  EXPECT_NE(page.find("Pareto front"), std::string::npos);
  const std::string summary = slurp(s.dir / "st" / "report" / "summary.md");
  EXPECT_NE(summary.find("| unit kind | busy |"), std::string::npos) << summary;
  EXPECT_NE(summary.find("| spp | cloth RMSE | cloth bias | eight-layers RMSE |"), std::string::npos)
      << "the quality-against-silicon table (lk's points; enderton and opaque have no reference RTL):\n"
      << summary;
  EXPECT_NE(summary.find("16 of 24 points have no silicon cost"), std::string::npos) << summary;
  EXPECT_NE(
      summary.find("| input | target RMSE | curve | spp | between swept spp | RMSE at them | cycles | DRAM bytes |"),
      std::string::npos)
      << "the equal-quality table:\n"
      << summary;
  // Written again over itself: the same files, nothing left behind.
  ASSERT_EQ(ropsim(s.dir, "study report st").status, 0);
  EXPECT_EQ(std::distance(fs::directory_iterator(s.dir / "st" / "report"), fs::directory_iterator()), 2);
}

TEST(StudyReport, AFailedPointAndOnlyFunctionalPointsStillGiveAReportThatRenders) {
  ReportScratch s;
  // A point fails at run time: its trace input exists when the study is
  // loaded, but is not a trace (a bad value in the study file is refused
  // before anything runs instead).
  ASSERT_EQ(ropsim(s.dir, "scene eight-layers --spp 4 --width 24 --height 24 -o good.trace").status, 0);
  s.put("notatrace.rtr", "this is not a trace\n");
  s.put("func.toml", R"(
[study]
name = "report-functional"

[inputs]
traces = ["good.trace", "notatrace.rtr"]

[axes]
method = ["lk", "enderton"]
)");
  const Ran run = ropsim(s.dir, "study run func.toml --out st -j 1 --quiet");
  ASSERT_EQ(run.status, 1) << "a point fails:\n" << run.err << run.out;
  const Ran rep = ropsim(s.dir, "study report st");
  ASSERT_EQ(rep.status, 0) << rep.err << rep.out;
  // Figures: RMSE against the functional state bytes only; no numeric axis
  // with two values, no cycle point, no saved image: sentences instead.
  const std::string page = check_report(
      s.dir, s.dir / "st", 1, {"Study report-functional", "Failures", "Quality against cost", "Image strips"});
  EXPECT_NE(page.find("4 points: 2 ok, 2 failed"), std::string::npos) << page.substr(0, 2000);
  EXPECT_NE(page.find("No cycle-fidelity point ran"), std::string::npos);
  EXPECT_NE(page.find("No swept numeric parameter has more than one value"), std::string::npos);
  EXPECT_NE(page.find("No point saved its image"), std::string::npos);
  EXPECT_NE(page.find("input=notatrace"), std::string::npos) << "the failures table names the point's parameters";
}

TEST(StudyReport, AFolderThatIsNotAStudyIsAOneLineError) {
  ReportScratch s;
  fs::create_directories(s.dir / "empty");
  for (const std::string d : {"empty", "nosuch"}) {
    const Ran r = ropsim(s.dir, "study report " + d);
    EXPECT_EQ(r.status, 1) << d;
    EXPECT_EQ(r.err.rfind("study_report: error: " + d + ": ", 0), 0u) << r.err;
    EXPECT_EQ(count(r.err, "\n"), 1u) << "one line:\n" << r.err;
    EXPECT_FALSE(fs::exists(s.dir / d / "report")) << d;
  }
}

// The built-in smoke study (studies/smoke.toml), end to end as CI runs it:
// every point ok in the database, the CSV export, the report rendering in
// headless Chromium.
TEST(StudyReport, TheBuiltInSmokeStudyRunsEndToEnd) {
  ReportScratch s;
  const Ran run = ropsim(s.dir, "study run '" ROPSIM_SOURCE_DIR "/studies/smoke.toml' --out st -j 2 --quiet");
  ASSERT_EQ(run.status, 0) << run.err << run.out;
  const Ran csv = ropsim(s.dir, "study export st --csv st.csv");
  ASSERT_EQ(csv.status, 0) << csv.err;
  const std::string table = slurp(s.dir / "st.csv");
  EXPECT_EQ(count(table, "\n"), 61u) << "a header and 60 points";
  EXPECT_EQ(count(table, ",ok,"), 60u) << "every point ok";
  const Ran rep = ropsim(s.dir, "study report st");
  ASSERT_EQ(rep.status, 0) << rep.err << rep.out;
  const size_t images = count(slurp(s.dir / "st" / "report" / "index.html"), "<img");
  EXPECT_GE(images, 8u) << "quality against cost, parameters, bottlenecks and image strips";
  const std::string page = check_report(s.dir, s.dir / "st", images,
                                        {"Study smoke", "Points", "Quality against cost", "Parameters against metrics",
                                         "Bottlenecks and stall reasons", "Image strips"});
  EXPECT_NE(page.find("60 points: 60 ok, 0 failed"), std::string::npos);
}
