// `ropsim study report` (docs/studies.md "The report"), through the real
// ropsim binary and a real headless Chromium: the report of a small study is
// written (index.html and summary.md), references no external resource, and
// renders in the browser with its headings, every image decoded and no failed
// resource load; every figure is readable at 100 % in a 1400-pixel-wide
// window (its layout, from the artists matplotlib drew: no text clipped or
// smaller than 10 px as shown, no legend on the data, no overlapping labels,
// no offset tick text); each image of a strip is captioned by the point it
// shows; a study of several fidelities has a section comparing them with the
// cycle model; a study with a failed point and only functional points still
// gives a report that renders; a folder that is not a study is a one-line
// error.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "tests/study_test_util.h"

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
/// The window the report is read in: 1400 CSS pixels wide at 100 % zoom.
constexpr int kWindowWidth = 1400;
std::string chromium(const fs::path& work) {
  // As root Chromium needs --no-sandbox; a fresh profile per run keeps
  // concurrent tests apart.
  const fs::path profile = work / ".chromium-profile";
  return "timeout 120 chromium --headless --no-sandbox --disable-gpu --no-first-run --disable-extensions "
         "--hide-scrollbars --force-device-scale-factor=1 --user-data-dir='" +
         profile.string() + "' --enable-logging=stderr --v=0 ";
}
Rendered render(const fs::path& work, const fs::path& page) {
  // The DOM is dumped after the load event.
  const Ran r = shell(work, chromium(work) + "--window-size=" + std::to_string(kWindowWidth) +
                                ",1000 --dump-dom 'file://" + fs::absolute(page).string() + "'");
  return Rendered{r.status, r.out, r.err};
}
/// A screenshot of the page's first `height` pixels in the window: its
/// width, height and number of dark pixels (text, lines, markers), read by
/// /usr/bin/python3's matplotlib.
struct Shot {
  int width = 0, height = 0;
  long dark = 0;
};
Shot screenshot(const fs::path& work, const fs::path& page, int height) {
  const fs::path png = work / "screenshot.png";
  const Ran r =
      shell(work, chromium(work) + "--window-size=" + std::to_string(kWindowWidth) + "," + std::to_string(height) +
                      " --screenshot='" + png.string() + "' 'file://" + fs::absolute(page).string() + "'");
  EXPECT_EQ(r.status, 0) << r.err;
  const Ran py = shell(work,
                       "/usr/bin/python3 -c 'import sys, matplotlib.image as m; a = m.imread(sys.argv[1]); "
                       "print(a.shape[1], a.shape[0], int((a[..., :3].sum(axis=-1) < 1.5).sum()))' '" +
                           png.string() + "'");
  Shot s;
  std::istringstream(py.out) >> s.width >> s.height >> s.dark;
  return s;
}

std::string html_unescape(const std::string& s) {
  static const std::pair<const char*, char> kEntities[] = {
      {"&quot;", '"'}, {"&#x27;", '\''}, {"&lt;", '<'}, {"&gt;", '>'}, {"&amp;", '&'}};
  std::string out;
  for (size_t i = 0; i < s.size();) {
    bool hit = false;
    if (s[i] == '&')
      for (const auto& [e, c] : kEntities)
        if (s.compare(i, std::strlen(e), e) == 0) {
          out += c;
          i += std::strlen(e);
          hit = true;
          break;
        }
    if (!hit) out += s[i++];
  }
  return out;
}

/// The start tags named `name` (e.g. "img", "figure") of a page, in order.
std::vector<std::string> start_tags(const std::string& page, const std::string& name) {
  std::vector<std::string> tags;
  const std::string open = "<" + name + " ";
  for (size_t at = page.find(open); at != std::string::npos; at = page.find(open, at + 1))
    tags.push_back(page.substr(at, page.find('>', at) - at + 1));
  return tags;
}
/// The (unescaped) value of attribute a of a start tag; "" if absent.
std::string attr(const std::string& tag, const std::string& a) {
  const std::string key = " " + a + "=\"";
  const size_t at = tag.find(key);
  if (at == std::string::npos) return "";
  const size_t v = at + key.size();
  return html_unescape(tag.substr(v, tag.find('"', v) - v));
}

std::vector<unsigned char> base64_decode(const std::string& s) {
  std::vector<unsigned char> out;
  uint32_t acc = 0;
  int bits = 0;
  for (char c : s) {
    int v = c >= 'A' && c <= 'Z'   ? c - 'A'
            : c >= 'a' && c <= 'z' ? c - 'a' + 26
            : c >= '0' && c <= '9' ? c - '0' + 52
            : c == '+'             ? 62
            : c == '/'             ? 63
                                   : -1;
    if (v < 0) continue;
    acc = (acc << 6) | uint32_t(v);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out.push_back(static_cast<unsigned char>((acc >> bits) & 0xff));
    }
  }
  return out;
}
/// The bytes of an <img>'s data: URI.
std::string img_bytes(const std::string& tag) {
  const std::string src = attr(tag, "src"), head = "data:image/png;base64,";
  if (src.rfind(head, 0) != 0) return "";
  const auto b = base64_decode(src.substr(head.size()));
  return std::string(b.begin(), b.end());
}

/// A box [x0, y0, x1, y1] in pixels, y down.
struct Box {
  double x0, y0, x1, y1;
};
Box box(const nlohmann::json& j) {
  return Box{j[0].get<double>(), j[1].get<double>(), j[2].get<double>(), j[3].get<double>()};
}
bool overlap(const Box& a, const Box& b, double by = 1.0) {
  return std::min(a.x1, b.x1) - std::max(a.x0, b.x0) > by && std::min(a.y1, b.y1) - std::max(a.y0, b.y0) > by;
}
bool inside(double x, double y, const Box& b) { return x > b.x0 && x < b.x1 && y > b.y0 && y < b.y1; }

/// The figures of a report (the <img>s with a data-layout), by name: their
/// layout. Checks, for each as the browser shows it (dom: the page after
/// load, whose script sets data-shown on each image) in a kWindowWidth
/// window: shown at its own size (not scaled down), every text at least
/// 10 px, inside the figure (no clipped title or label) and, but annotations
/// and legend entries, clear of every other; no legend over an axes or a
/// data point; no offset text on an axis.
std::map<std::string, nlohmann::json> check_figures(const std::string& dom) {
  std::map<std::string, nlohmann::json> figures;
  for (const std::string& tag : start_tags(dom, "img")) {
    const std::string text = attr(tag, "data-layout");
    if (text.empty()) continue;
    const nlohmann::json l = nlohmann::json::parse(text);
    const std::string name = l["figure"].get<std::string>();
    figures[name] = l;
    const double w = l["width"].get<double>(), h = l["height"].get<double>();
    std::istringstream shown(attr(tag, "data-shown"));
    double left = 0, top = 0, sw = 0, sh = 0;
    shown >> left >> top >> sw >> sh;
    EXPECT_NEAR(sw, w, 0.6) << name << ": shown " << sw << " px wide, drawn " << w << " (scaled in the page)";
    const double scale = sw > 0 ? sw / w : 0;
    std::vector<std::pair<std::string, Box>> layout;
    for (const auto& t : l["texts"]) {
      const std::string s = t["text"].get<std::string>();
      const Box b = box(t["bbox"]);
      EXPECT_GE(t["px"].get<double>() * scale, 10.0) << name << ": text \"" << s << "\" is smaller than 10 px";
      EXPECT_TRUE(b.x0 >= -1 && b.y0 >= -1 && b.x1 <= w + 1 && b.y1 <= h + 1)
          << name << ": text \"" << s << "\" is clipped: [" << b.x0 << ", " << b.y0 << ", " << b.x1 << ", " << b.y1
          << "] in " << w << " x " << h;
      if (t["kind"] == "layout") layout.emplace_back(s, b);
    }
    for (size_t i = 0; i < layout.size(); ++i)
      for (size_t k = i + 1; k < layout.size(); ++k)
        EXPECT_FALSE(overlap(layout[i].second, layout[k].second))
            << name << ": \"" << layout[i].first << "\" overlaps \"" << layout[k].first << "\"";
    for (const auto& lg : l["legends"]) {
      const Box b = box(lg);
      for (const auto& a : l["axes"]) {
        EXPECT_FALSE(overlap(b, box(a["bbox"]), 0.0)) << name << ": a legend lies over the panel " << a["title"];
        for (const auto& p : a["points"])
          EXPECT_FALSE(inside(p[0].get<double>(), p[1].get<double>(), b)) << name << ": a legend hides a data point";
      }
    }
    for (const auto& a : l["axes"])
      for (const auto& o : a["offset_text"]) EXPECT_EQ(o.get<std::string>(), "") << name << ": offset tick text";
  }
  return figures;
}

bool have_chromium() { return std::system("command -v chromium >/dev/null 2>&1") == 0; }

/// Checks the report under study_dir/report: both files, no external
/// resource, and in the browser the headings, `images` images all decoded, no
/// failed resource load and every figure readable (check_figures). Returns
/// the HTML; the DOM after the load event into *dom, the figures' layouts into
/// *figures.
std::string check_report(const fs::path& work, const fs::path& study_dir, size_t images,
                         const std::vector<std::string>& headings, std::string* dom = nullptr,
                         std::map<std::string, nlohmann::json>* figures = nullptr) {
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
  const auto laid_out = check_figures(r.dom);
  size_t plots = 0;  // the <img>s drawn by matplotlib: all but a strip's images
  for (const std::string& tag : start_tags(page, "img"))
    plots += attr(tag, "data-role").empty() || attr(tag, "data-role") == "colour-bar";
  EXPECT_EQ(laid_out.size(), plots) << "every plot carries its layout (data-layout), under a name of its own";
  if (dom) *dom = r.dom;
  if (figures) *figures = laid_out;
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
  // against spp and against the fidelity, per input; the fidelities against
  // the cycle model; bottleneck classes; cycles by activity. Images: per
  // input the reference and the error maps' colour bar, and per method its
  // image and its error map.
  const std::string page = check_report(
      s.dir, s.dir / "st", 3 + 1 + 2 * 2 + 1 + 1 + 1 + 2 * (2 + 3 * 2),
      {"Study report-small", "Points", "Failures", "Quality against cost", "Equal quality", "Quality against silicon",
       "Parameters against metrics", "Fidelities", "Bottlenecks and stall reasons", "Image strips"});
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

// Each image of a strip is the image of the point its <figure> names
// (data-point: its bytes are the point's image.png), captioned with that
// point's method and spp from the results, with that point's error map
// under it in the same column as the browser lays the page out.
TEST(StudyReport, EachImageIsCaptionedByThePointItShows) {
  ReportScratch s;
  s.put("strip.toml", R"(
[study]
name = "report-strip"
save_images = true

[inputs]
scenes = ["cloth", "eight-layers"]

[axes]
method = ["lk", "naive", "a2c", "opaque"]
spp = [4, 8]
width = 24
height = 24
)");
  ASSERT_EQ(ropsim(s.dir, "study run strip.toml --out st -j 2 --quiet").status, 0);
  ASSERT_EQ(ropsim(s.dir, "study report st").status, 0);
  std::map<std::string, std::map<std::string, std::string>> by_point;
  for (const auto& row : export_rows(s.dir, "st")) by_point[row.at("point")] = row;
  std::string dom;
  const std::string page = check_report(
      s.dir, s.dir / "st", 0 + count(slurp(s.dir / "st" / "report" / "index.html"), "<img"), {"Image strips"}, &dom);
  // The strips: per input a <div class="strip" data-input=...>, in it one
  // <figure data-point=...> per method at the input's largest spp.
  size_t figures = 0;
  for (const std::string& strip : {std::string("cloth"), std::string("eight-layers")}) {
    const size_t from = page.find("<div class=\"strip\" data-input=\"" + strip + "\"");
    ASSERT_NE(from, std::string::npos) << "no strip for " << strip;
    const std::string div = page.substr(from, page.find("</div>", from) - from);
    std::vector<std::string> methods;
    for (size_t at = div.find("<figure data-point="); at != std::string::npos;
         at = div.find("<figure data-point=", at + 1)) {
      const std::string fig = div.substr(at, div.find("</figure>", at) - at);
      const std::string tag = fig.substr(0, fig.find('>') + 1), h = attr(tag, "data-point");
      ASSERT_TRUE(by_point.count(h)) << "data-point " << h << " is no point of the study";
      const auto& row = by_point[h];
      ++figures;
      methods.push_back(row.at("method"));
      EXPECT_EQ(row.at("input"), strip) << h;
      EXPECT_EQ(row.at("spp"), "8") << h << ": the strip shows the largest spp";
      EXPECT_EQ(attr(tag, "data-method"), row.at("method")) << h;
      EXPECT_EQ(attr(tag, "data-spp"), row.at("spp")) << h;
      const size_t cap = fig.find("<figcaption>");
      ASSERT_NE(cap, std::string::npos);
      const std::string want = row.at("method") + ", " + row.at("spp") + " spp<br>";
      EXPECT_EQ(fig.compare(cap + 12, want.size(), want), 0)
          << "the caption of " << h << " is not its row's method and spp: " << fig.substr(cap, 80);
      const auto imgs = start_tags(fig, "img");
      ASSERT_EQ(imgs.size(), 2u) << h << ": its image and its error map";
      EXPECT_EQ(attr(imgs[0], "data-role"), "image");
      EXPECT_EQ(attr(imgs[1], "data-role"), "error");
      for (const auto& img : imgs) EXPECT_EQ(attr(img, "data-point"), h);
      EXPECT_EQ(img_bytes(imgs[0]), slurp(s.dir / "st" / "points" / h / "image.png"))
          << h << ": the image shown is not the point's image.png";
    }
    EXPECT_EQ(methods, (std::vector<std::string>{"lk", "naive", "a2c", "opaque"})) << strip;
  }
  EXPECT_EQ(figures, 8u);
  // In the browser: each error map right under its own image.
  std::map<std::string, std::vector<double>> image_at, error_at;
  for (const std::string& tag : start_tags(dom, "img")) {
    std::istringstream in(attr(tag, "data-shown"));
    std::vector<double> v(4);
    in >> v[0] >> v[1] >> v[2] >> v[3];
    if (attr(tag, "data-role") == "image") image_at[attr(tag, "data-point")] = v;
    if (attr(tag, "data-role") == "error") error_at[attr(tag, "data-point")] = v;
  }
  ASSERT_EQ(image_at.size(), 8u);
  for (const auto& [h, im] : image_at) {
    ASSERT_TRUE(error_at.count(h)) << h;
    const auto& e = error_at[h];
    EXPECT_NEAR(e[0], im[0], 0.5) << by_point[h].at("method") << ": the error map is not under its image";
    EXPECT_NEAR(e[2], im[2], 0.5) << "the error map is as wide as the image";
    EXPECT_GT(e[1], im[1] + im[3] - 0.5) << "the error map lies below the image";
    EXPECT_LT(e[1], im[1] + im[3] + 20) << "and right under it";
    EXPECT_GE(im[2], 48.0) << "a 24-pixel image is shown enlarged";
  }
}

// A study of several fidelities (studies/fidelity.toml, small): the report's
// "Fidelities" section lists each point against the cycle model's point of
// the same parameters: the estimate of total cycles with its 95 % interval
// (sampled points), the cycle model's value, the relative error and whether
// the value lies in the interval, the host time and the speed-up, all
// consistent with the results; analysis/fidelity.py's table names the cycle
// model as the reference and the functional points as untimed.
TEST(StudyReport, AStudyOfSeveralFidelitiesHasAFidelitySectionWithIntervals) {
  ReportScratch s;
  s.put("fid.toml", std::string(R"(
[study]
name = "report-fidelity"
reference = false

[inputs]
scenes = ["smoke"]

[axes]
method = "lk"
spp = 4
fidelity = ["functional", "approximate", "sampled", "cycle"]
sample_units = 6
sample_size = 500
sample_warmup = 1000
sample_cooldown = 500
design = [")") + ROPSIM_SOURCE_DIR +
                        R"(/configs/default.toml", ")" + ROPSIM_SOURCE_DIR + R"(/configs/narrow.toml"]
)");
  ASSERT_EQ(ropsim(s.dir, "study run fid.toml --out st -j 2 --quiet").status, 0);
  ASSERT_EQ(ropsim(s.dir, "study report st").status, 0);
  std::map<std::string, nlohmann::json> figures;
  check_report(s.dir, s.dir / "st", count(slurp(s.dir / "st" / "report" / "index.html"), "<img"),
               {"Study report-fidelity", "Fidelities"}, nullptr, &figures);
  EXPECT_TRUE(figures.count("fidelity")) << "the fidelities' figure";
  // The cycle points' total cycles and host time per design.
  const Rows rows = export_rows(s.dir, "st");
  std::map<std::string, double> cycle_cycles, cycle_host;
  for (const auto& r : rows)
    if (r.at("fidelity") == "cycle") {
      const std::string d = fs::path(r.at("design")).stem().string();
      cycle_cycles[d] = std::stod(r.at("timing.total_cycles"));
      cycle_host[d] = std::stod(r.at("host.wall_seconds"));
    }
  ASSERT_EQ(cycle_cycles.size(), 2u);
  // The per-point table in summary.md.
  const std::string md = slurp(s.dir / "st" / "report" / "summary.md");
  const std::string head =
      "| point | fidelity | total cycles | 95 % interval | cycle model | cycles error | cycle value in interval |";
  const size_t at = md.find(head);
  ASSERT_NE(at, std::string::npos) << md;
  std::istringstream table(md.substr(at));
  std::string line;
  std::getline(table, line);
  std::getline(table, line);  // |---|
  std::map<std::string, size_t> seen;
  while (std::getline(table, line) && line.rfind("| ", 0) == 0) {
    std::vector<std::string> c;
    std::istringstream cells(line.substr(2));
    for (std::string f; std::getline(cells, f, '|');)
      c.push_back(f.substr(0, f.find_last_not_of(' ') + 1)
                      .substr(f.find_first_not_of(' ') == std::string::npos ? 0 : f.find_first_not_of(' ')));
    ASSERT_GE(c.size(), 15u) << line;
    const std::string fid = c[1];
    ++seen[fid];
    if (fid == "functional") {
      EXPECT_EQ(c[2], "") << "a functional point has no cycles: " << line;
      EXPECT_GT(std::stod(c[14]), 0.0) << "but a speed-up: " << line;
      continue;
    }
    const std::string design = c[0].substr(c[0].find("design=") + 7);
    ASSERT_TRUE(cycle_cycles.count(design)) << line;
    const double est = std::stod(c[2]), truth = std::stod(c[4]);
    EXPECT_NEAR(truth, cycle_cycles[design], 0.5) << "the cycle model's value: " << line;
    EXPECT_NEAR(std::stod(c[5]), 100.0 * (est - truth) / truth, 0.006) << "the relative error: " << line;
    EXPECT_NEAR(std::stod(c[14]), cycle_host[design] / std::stod(c[13]), 0.01 + 0.02 * std::stod(c[14]))
        << "the speed-up: " << line;
    if (fid == "sampled") {
      double lo = 0, hi = 0;
      ASSERT_EQ(std::sscanf(c[3].c_str(), "[%lf, %lf]", &lo, &hi), 2) << "a sampled point's interval: " << line;
      EXPECT_LE(lo, est);
      EXPECT_GE(hi, est);
      EXPECT_EQ(c[6], lo <= truth && truth <= hi ? "yes" : "no") << line;
      EXPECT_TRUE(c[8] == "yes" || c[8] == "no") << "the bytes read's interval: " << line;
    } else {
      EXPECT_EQ(c[3], "") << "only a sampled point has an interval: " << line;
    }
  }
  EXPECT_EQ(seen["sampled"], 2u);
  EXPECT_EQ(seen["approximate"], 2u);
  EXPECT_EQ(seen["functional"], 1u);
  EXPECT_NE(md.find("| cycle | 2 |"), std::string::npos) << "the summary's cycle row:\n" << md;
  // analysis/fidelity.py on the same folder.
  const Ran f =
      shell(s.dir, "/usr/bin/python3 -W error::RuntimeWarning '" ROPSIM_SOURCE_DIR "/analysis/fidelity.py' st");
  ASSERT_EQ(f.status, 0) << f.err;
  EXPECT_EQ(f.err, "");
  EXPECT_NE(f.out.find("| cycle | 2 | "), std::string::npos) << f.out;
  EXPECT_NE(f.out.find("| the reference |"), std::string::npos) << f.out;
  EXPECT_NE(f.out.find("| functional | 1 | "), std::string::npos) << f.out;
  EXPECT_NE(f.out.find("no timing"), std::string::npos) << f.out;
  EXPECT_EQ(f.out.find("x less"), std::string::npos) << f.out;
  EXPECT_NE(f.out.find("x faster"), std::string::npos) << f.out;
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
  EXPECT_NE(page.find("No swept parameter has more than one value"), std::string::npos);
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
  std::map<std::string, nlohmann::json> figures;
  const std::string page = check_report(s.dir, s.dir / "st", images,
                                        {"Study smoke", "Points", "Quality against cost", "Parameters against metrics",
                                         "Fidelities", "Bottlenecks and stall reasons", "Image strips"},
                                        nullptr, &figures);
  EXPECT_NE(page.find("60 points: 60 ok, 0 failed"), std::string::npos);
  EXPECT_NE(page.find("<td>spp</td><td>4, 16</td>"), std::string::npos) << "values sorted numerically";
  // Every swept parameter against the metrics, a figure per input, frame
  // time beside cycles; the quality figures with logarithmic axes where the
  // values span a decade and the frame time over the cycles.
  for (const std::string p : {"spp", "fidelity", "distributor.rop_units"})
    for (const std::string in : {"cloth", "eight-layers"})
      EXPECT_TRUE(figures.count("axes:" + p + ":" + in)) << "no figure of the metrics against " << p << " for " << in;
  ASSERT_TRUE(figures.count("axes:spp:cloth"));
  std::vector<std::string> titles;
  for (const auto& a : figures["axes:spp:cloth"]["axes"]) titles.push_back(a["title"].get<std::string>());
  const auto cycles = std::find(titles.begin(), titles.end(), "total cycles");
  ASSERT_NE(cycles, titles.end());
  ASSERT_NE(cycles + 1, titles.end());
  EXPECT_EQ(cycles[1], "frame time (µs)") << "frame time beside cycles";
  ASSERT_TRUE(figures.count("quality:dram"));
  bool log_x = false;
  for (const auto& a : figures["quality:dram"]["axes"]) log_x |= a["xscale"] == "log";
  EXPECT_TRUE(log_x) << "DRAM bytes from 4 to 16 spp and 1 to 4 ROPs span a decade";
  ASSERT_TRUE(figures.count("quality:cycles"));
  EXPECT_NE(figures["quality:cycles"].dump().find("frame time (µs) at 1.5 GHz"), std::string::npos);
  // The page as the reader sees it: 1400 pixels wide, drawn.
  if (have_chromium()) {
    const Shot shot = screenshot(s.dir, s.dir / "st" / "report" / "index.html", 2400);
    EXPECT_EQ(shot.width, kWindowWidth);
    EXPECT_EQ(shot.height, 2400);
    EXPECT_GT(shot.dark, long(kWindowWidth) * 20) << "the screenshot shows text and plots";
  }
}

// The section "Against blend" from a results table of known values (written
// with Python's sqlite3, as `ropsim study run` writes it): the ratios to
// blend, whether blend's error is the larger, the marginal cost, the spp at
// which a method reaches blend's RMSE, and the opaque frame's table.
TEST(StudyReport, AgainstBlendGivesRatiosMarginalCostAndTheSppThatReachesBlend) {
  ReportScratch s;
  s.put("study.toml", R"(
[study]
name = "against-blend"
[axes]
method = ["blend", "lk"]
spp = [4, 16, 64]
)");
  // glass: blend's order error is 2.04 at every spp; lk's RMSE is
  // 12/sqrt(spp) (6, 3, 1.5), so it reaches 2.04 at (12/2.04)^2 = 34.6 spp.
  // lk costs 1.5x blend's cycles and 2x its DRAM bytes. box: all opaque,
  // lk's image is blend's and it costs 100 cycles and 64 bytes more.
  s.put("make.py", R"py(import sqlite3
con = sqlite3.connect("st/results.db")
con.execute('CREATE TABLE results (point TEXT, point_index INTEGER, status TEXT, input TEXT, method TEXT, spp INTEGER,'
            ' fidelity TEXT, "vs_reference.rmse_8bit" REAL, "timing.total_cycles" REAL,'
            ' "timing.dram.bytes_read" REAL, "timing.dram.bytes_written" REAL, "frame.transparent_share" REAL)')
con.execute("CREATE TABLE study (key TEXT, value TEXT)")
con.execute("INSERT INTO study VALUES ('name', 'against-blend')")
rows, i = [], 0
for spp in (4, 16, 64):
    rows.append(("glass", "blend", spp, 2.04, 1000 * spp, 300 * spp, 100 * spp, 0.5))
    rows.append(("glass", "lk", spp, 12 / spp ** 0.5, 1500 * spp, 600 * spp, 200 * spp, 0.5))
    rows.append(("box", "blend", spp, 0.0, 500 * spp, 100 * spp, 100 * spp, 0.0))
    rows.append(("box", "lk", spp, 0.0, 500 * spp + 100, 100 * spp + 64, 100 * spp, 0.0))
for r in rows:
    con.execute("INSERT INTO results VALUES (?, ?, 'ok', ?, ?, ?, 'cycle', ?, ?, ?, ?, ?)", ("p%d" % i, i) + r)
    i += 1
con.commit()
)py");
  fs::create_directories(s.dir / "st");
  fs::copy_file(s.dir / "study.toml", s.dir / "st" / "study.toml");
  ASSERT_EQ(shell(s.dir, "/usr/bin/python3 make.py").status, 0);
  const Ran rep = ropsim(s.dir, "study report st");
  ASSERT_EQ(rep.status, 0) << rep.err << rep.out;
  const std::string md = slurp(s.dir / "st" / "report" / "summary.md");
  const size_t at = md.find("## Against blend\n");
  ASSERT_NE(at, std::string::npos) << md;
  const std::string sec = md.substr(at, md.find("\n## ", at + 1) - at);
  // input | point | method | RMSE | blend's RMSE | blend's error larger | cycles | x blend | DRAM bytes | x blend
  EXPECT_NE(sec.find("| glass | spp=4 | lk | 6 | 2.04 | no | 6000 | 1.5 | 3200 | 2 |"), std::string::npos) << sec;
  EXPECT_NE(sec.find("| glass | spp=64 | lk | 1.5 | 2.04 | yes | 96000 | 1.5 | 51200 | 2 |"), std::string::npos) << sec;
  // The marginal cost by spp and where lk reaches blend's RMSE.
  EXPECT_NE(sec.find("| glass |  | lk | 4: +2,000, 16: +8,000, 64: +32,000 | 4: +1,600 (+100%), 16: +6,400 (+100%), "
                     "64: +25,600 (+100%) | 34.6 spp; blend 2.04 |"),
            std::string::npos)
      << sec;
  EXPECT_NE(sec.find("| box |  | lk | 4: +100, 16: +100, 64: +100 | 4: +64 (+8%), 16: +64 (+2%), 64: +64 (+0%) | "
                     "at or below 4 spp; blend 0 |"),
            std::string::npos)
      << sec;
  // The all-opaque frame's table: lk's image is blend's; what its opaque draws cost beyond.
  EXPECT_NE(sec.find("| box | spp=16 | lk | 0 | +100 | +64 |"), std::string::npos) << sec;
  EXPECT_EQ(sec.find("| glass | spp=16 | lk | 0 |"), std::string::npos)
      << "a frame with transparent samples is not in it";
  // docs/results.md's tables and figure of the same (analysis/real_frames.py).
  const Ran rf = shell(
      s.dir, "/usr/bin/python3 '" ROPSIM_SOURCE_DIR "/analysis/real_frames.py' st --markdown rf.md --plot rf.png");
  ASSERT_EQ(rf.status, 0) << rf.err << rf.out;
  const std::string t = slurp(s.dir / "rf.md");
  EXPECT_NE(t.find("| glass |  | lk | 3 | no | 24,000 | 1.500 | 12,800 | 2.000 |"), std::string::npos) << t;
  EXPECT_NE(t.find("| glass |  | lk | 4: +2,000 (+50%); 16: +8,000 (+50%); 64: +32,000 (+50%) | 4: +1,600 (+100%); "
                   "16: +6,400 (+100%); 64: +25,600 (+100%) | 2.04 | 34.6 |"),
            std::string::npos)
      << t;
  EXPECT_GT(fs::file_size(s.dir / "rf.png"), 10000u) << "the figure";
}
