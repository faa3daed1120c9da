#include "util/progress.h"

#include <unistd.h>

#include <atomic>
#include <cmath>
#include <cstdio>

namespace ropsim {

namespace {
std::atomic<ProgressMode> g_mode{ProgressMode::kOff};
}

void set_progress_mode(ProgressMode m) { g_mode.store(m); }
ProgressMode progress_mode() { return g_mode.load(); }

Progress::Progress(std::string label, std::string unit)
    : label_(std::move(label)), unit_(std::move(unit)), t0_(std::chrono::steady_clock::now()) {
  const ProgressMode m = progress_mode();
  tty_ = ::isatty(2) == 1;
  on_ = m == ProgressMode::kAlways || (m == ProgressMode::kTerminal && tty_);
  // The first log line after one period; a terminal line at once.
  last_ = tty_ ? t0_ - std::chrono::seconds(1) : t0_;
}

Progress::Progress(Text text, bool shown) : text_(std::move(text)), t0_(std::chrono::steady_clock::now()) {
  tty_ = ::isatty(2) == 1;
  on_ = shown;
  // The first line at once, on a terminal and in a log.
  last_ = t0_ - std::chrono::seconds(2 * kLogPeriod);
}

// Not finished (an exception on its way): end a terminal line, claim no 100 %.
Progress::~Progress() {
  if (!finished_ && on_ && printed_ && tty_) std::fputs("\n", stderr);
}

std::string Progress::format_duration(double s) {
  char b[48];
  if (!(s >= 0) || !std::isfinite(s)) return "?";
  if (s < 60) {
    std::snprintf(b, sizeof b, "%.1f s", s);
  } else if (s < 3600) {
    const long t = std::lround(s);
    std::snprintf(b, sizeof b, "%ld min %02ld s", t / 60, t % 60);
  } else {
    const long t = std::lround(s / 60);
    std::snprintf(b, sizeof b, "%ld h %02ld min", t / 60, t % 60);
  }
  return b;
}

std::string Progress::line(const std::string& label, const std::string& unit, double fraction, uint64_t done,
                           double elapsed_s) {
  char b[256];
  std::string s = label + ":";
  if (fraction >= 0) {
    std::snprintf(b, sizeof b, " %5.1f %%,", 100.0 * std::min(fraction, 1.0));
    s += b;
  }
  const double rate = elapsed_s > 0 ? double(done) / elapsed_s : 0;
  if (done >= 10'000'000)
    std::snprintf(b, sizeof b, " %.1f M %s", double(done) / 1e6, unit.c_str());
  else
    std::snprintf(b, sizeof b, " %llu %s", (unsigned long long)done, unit.c_str());
  s += b;
  if (rate >= 1e6)
    std::snprintf(b, sizeof b, " (%.2f M/s)", rate / 1e6);
  else if (rate >= 1e4)
    std::snprintf(b, sizeof b, " (%.1f k/s)", rate / 1e3);
  else
    std::snprintf(b, sizeof b, " (%.1f /s)", rate);
  s += b;
  s += ", " + format_duration(elapsed_s);
  // The ETA once the rate is known: 1 % consumed or a second elapsed.
  if (fraction > 0 && fraction < 1 && (fraction >= 0.01 || elapsed_s >= 1.0))
    s += ", ETA " + format_duration(elapsed_s * (1.0 - fraction) / fraction);
  return s;
}

void Progress::print(double fraction, uint64_t done, bool final) {
  const double el = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count();
  const std::string l = text_ ? text_(el) : line(label_, unit_, fraction, done, el);
  if (tty_)
    std::fprintf(stderr, "\r  %s   %s", l.c_str(), final ? "\n" : "");
  else
    std::fprintf(stderr, "  %s\n", l.c_str());
  std::fflush(stderr);
  printed_ = true;
}

void Progress::update(double fraction, uint64_t done) {
  fraction_ = fraction;
  done_ = done;
  if (!on_ || finished_) return;
  const auto now = std::chrono::steady_clock::now();
  if (now - last_ < (tty_ ? std::chrono::milliseconds(100) : std::chrono::milliseconds(kLogPeriod))) return;
  last_ = now;
  print(fraction, done, false);
}

void Progress::tick() { update(fraction_, done_); }

void Progress::finish() {
  if (finished_) return;
  finished_ = true;
  // On a terminal, the line shown is completed; in a log (--progress), a
  // run too short for a periodic line still gets its final one.
  if (on_ && (printed_ || !tty_)) print(fraction_ >= 0 ? 1.0 : -1.0, done_, true);
}

}  // namespace ropsim
