// Progress of a long run on stderr: how much of the input is consumed, the
// rate, and the time left (ETA). A process setting, like host_threads(), set
// once by the CLI: shown on a terminal by default, forced into logs by
// --progress (a line every few seconds instead of a line redrawn in place),
// never with --quiet, and never in a process that did not ask (a study's
// worker, a test). Bottom layer: the standard library only.
#pragma once
#include <chrono>
#include <cstdint>
#include <functional>
#include <string>

namespace ropsim {

enum class ProgressMode {
  kOff,       ///< nothing (the default of a process that sets nothing)
  kTerminal,  ///< only if stderr is a terminal, redrawn in place (the CLI's default)
  kAlways,    ///< a line every kLogPeriod on any stderr, a log included (--progress)
};
void set_progress_mode(ProgressMode m);
ProgressMode progress_mode();

/// One progress line for one phase of a run ("functional", "cycle model",
/// "reference", "capture"...). update() is cheap when nothing is shown, and
/// throttled (100 ms on a terminal, kLogPeriod in a log); finish() prints
/// the last line (the destructor only ends a terminal line: a run that threw
/// is not shown as complete). Not thread-safe: one thread updates it.
class Progress {
 public:
  static constexpr std::chrono::seconds kLogPeriod{5};
  /// unit names what `done` counts ("fragments", "triangles").
  Progress(std::string label, std::string unit);
  /// A line whose text the caller makes (a study's points: "study NAME: 3 of
  /// 8 points done ..."), from the seconds elapsed; shown when `shown` (the
  /// verb's own choice, whatever the process's mode), redrawn in place on a
  /// terminal and a line every kLogPeriod in a log. tick() prints it when due.
  using Text = std::function<std::string(double elapsed_s)>;
  Progress(Text text, bool shown);
  ~Progress();
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;

  bool shown() const { return on_; }
  /// fraction: of the whole input consumed, in [0, 1] (negative: unknown,
  /// then no percentage and no ETA); done: units processed so far.
  void update(double fraction, uint64_t done);
  /// The caller's line (the Text constructor), when it is due.
  void tick();
  /// The last line (100 %, the elapsed time), then a newline.
  void finish();

  /// "12.3 s", "4 min 05 s", "1 h 02 min": a duration for people.
  static std::string format_duration(double seconds);
  /// The line itself (no \r, no newline), for tests.
  static std::string line(const std::string& label, const std::string& unit, double fraction, uint64_t done,
                          double elapsed_s);

 private:
  void print(double fraction, uint64_t done, bool final);
  std::string label_, unit_;
  Text text_;
  bool on_ = false, tty_ = false, printed_ = false, finished_ = false;
  std::chrono::steady_clock::time_point t0_, last_;
  double fraction_ = -1;
  uint64_t done_ = 0;
};

}  // namespace ropsim
