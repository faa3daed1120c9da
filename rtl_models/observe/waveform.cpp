#include "rtl_models/observe/waveform.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <queue>

#include "util/errors.h"

namespace ropsim {

namespace {

constexpr size_t kChargeStep = size_t{1} << 20;  // the memory budget is charged per MiB of streams
// The VCD identifiers: the clock, the cycle counter, then the signals.
constexpr size_t kClk = 0, kCycle = 1, kFirstSignal = 2;
// Time units of 100 ps (VCD allows 1, 10 or 100 of a power-of-ten unit):
// ten per cycle, so a cycle is 1 ns; the clock falls half-way.
constexpr uint64_t kUnitsPerCycle = 10, kFall = 5;

// A VCD identifier: base 94 over the printable characters '!'..'~'.
std::string vcd_id(size_t i) {
  std::string s;
  do {
    s += char('!' + i % 94);
    i /= 94;
  } while (i);
  return s;
}

void put_binary(std::string& o, uint64_t v) {
  o += 'b';
  if (v == 0) {
    o += '0';
    return;
  }
  for (int b = 63 - __builtin_clzll(v); b >= 0; --b) o += char('0' + ((v >> b) & 1));
}

struct Reader {
  const uint8_t* p = nullptr;
  const uint8_t* end = nullptr;
  bool more() const { return p != end; }
  uint64_t next() {
    uint64_t v = 0;
    for (int shift = 0;; shift += 7) {
      const uint8_t b = *p++;
      v |= uint64_t(b & 0x7f) << shift;
      if (!(b & 0x80)) return v;
    }
  }
};

// The value of one signal cycle by cycle: next_t is the cycle of its next
// change (~0: none), advance() applies every event of that cycle.
struct Cursor {
  static constexpr uint64_t kNone = ~uint64_t{0};
  const Waveform::Signal* s;
  Reader r[2];
  uint64_t t[2];         // the cycle of each stream's next event (kNone: none)
  uint64_t pending = 0;  // kState, kCount: the next event's value
  uint64_t value = 0, pushes = 0, pops = 0;

  Cursor(const Waveform::Signal& sig, uint64_t first) : s(&sig) {
    for (int k = 0; k < 2; ++k) {
      r[k] = Reader{sig.stream[k].data(), sig.stream[k].data() + sig.stream[k].size()};
      t[k] = first;
      read(k);
    }
    pushes = sig.before[0];
    pops = sig.before[1];
    value = sig.kind == Waveform::Signal::Kind::kOccupancy ? pushes - pops : sig.initial;
  }
  void read(int k) {
    if (!r[k].more()) {
      t[k] = kNone;
      return;
    }
    t[k] += r[k].next();
    if (s->kind != Waveform::Signal::Kind::kOccupancy) pending = r[k].next();
  }
  uint64_t next_t() const { return std::min(t[0], t[1]); }
  void advance() {
    const uint64_t c = next_t();
    if (s->kind == Waveform::Signal::Kind::kOccupancy) {
      for (; t[0] == c; read(0)) ++pushes;
      for (; t[1] == c; read(1)) ++pops;
      value = pushes - pops;
    } else {
      for (; t[0] == c; read(0)) value = pending;  // the last set at a cycle wins
    }
  }
};

}  // namespace

Waveform::Waveform(uint64_t first, uint64_t last) : first_(first), last_(std::max(first, last)) {}

int Waveform::add_state(const std::string& scope, const std::string& name, std::vector<std::string> states) {
  invariant(!states.empty(), "a waveform state signal names at least one state");
  signals_.push_back(Signal{Signal::Kind::kState, scope, name, std::move(states), {}, {}, {}, 0});
  return int(signals_.size() - 1);
}

int Waveform::add_count(const std::string& scope, const std::string& name) {
  signals_.push_back(Signal{Signal::Kind::kCount, scope, name, {}, {}, {}, {}, 0});
  return int(signals_.size() - 1);
}

int Waveform::add_occupancy(const std::string& scope, const std::string& name) {
  signals_.push_back(Signal{Signal::Kind::kOccupancy, scope, name, {}, {}, {}, {}, 0});
  return int(signals_.size() - 1);
}

void Waveform::check_order(Signal& s, int which, uint64_t t) {
  if (t < s.last_t[which])
    throw InternalError("a waveform signal's events come in cycle order: " + s.scope + "." + s.name + " got cycle " +
                        std::to_string(t) + " after " + std::to_string(s.last_t[which]));
  s.last_t[which] = t;
}

void Waveform::append(Signal& s, int which, uint64_t v) {
  std::vector<uint8_t>& b = s.stream[which];
  const size_t before = b.size();
  do {
    b.push_back(uint8_t((v & 0x7f) | (v > 0x7f ? 0x80 : 0)));
    v >>= 7;
  } while (v);
  bytes_ += b.size() - before;
  if (bytes_ > mem_.bytes()) mem_.add(kChargeStep, "the --vcd waveform");
}

void Waveform::record(int sig, uint64_t t, uint64_t v) {
  Signal& s = signals_[size_t(sig)];
  const uint64_t prev = std::max(s.last_t[0], first_);
  check_order(s, 0, t);
  if (t <= first_) {  // the value the window starts with
    s.initial = v;
    return;
  }
  append(s, 0, t - prev);
  append(s, 0, v);
}

void Waveform::count_edge(int sig, uint64_t t, int which) {
  Signal& s = signals_[size_t(sig)];
  const uint64_t prev = std::max(s.last_t[which], first_);
  check_order(s, which, t);
  if (t <= first_) {  // in or out by the window's first cycle
    ++s.before[which];
    return;
  }
  append(s, which, t - prev);
}

std::vector<std::string> Waveform::ordered_scopes() const {
  // Scopes in the order of their first signal, each scope's signals
  // together; "a.b" is scope b inside scope a.
  std::vector<std::string> scopes;
  for (const auto& s : signals_)
    if (std::find(scopes.begin(), scopes.end(), s.scope) == scopes.end()) scopes.push_back(s.scope);
  // A nested scope's parents are listed once: group the scopes by their
  // first part in first-appearance order.
  std::vector<std::string> heads;  // first parts, in first-appearance order
  auto head = [](const std::string& x) { return x.substr(0, x.find('.')); };
  for (const auto& sc : scopes)
    if (std::find(heads.begin(), heads.end(), head(sc)) == heads.end()) heads.push_back(head(sc));
  auto rank = [&](const std::string& x) { return std::find(heads.begin(), heads.end(), head(x)) - heads.begin(); };
  std::stable_sort(scopes.begin(), scopes.end(),
                   [&](const std::string& a, const std::string& b) { return rank(a) < rank(b); });
  return scopes;
}

std::string Waveform::write_gtkw(const std::string& vcd_path, const std::string& top, uint64_t end) const {
  std::string o = "[*] ropsim: a GTKWave save file for " + vcd_path + "\n";
  o += "[dumpfile] \"" + vcd_path + "\"\n";
  // The window: cycles first..last, 1000 ps each (ten 100 ps time units).
  const uint64_t last = std::max(first_, last_shown(end));
  const double span_ps = double(last - first_ + 1) * 1000.0 * 1.02;  // a margin after the last cycle
  // GTKWave shows about kZoomScale x 2^-zoom ps across the wave pane of a
  // window of this [size] with these pane widths (measured with GTKWave
  // 3.3.118: Zoom Best Fit keeps the same relation).
  constexpr double kZoomScale = 3.30;
  char zoom[64];
  std::snprintf(zoom, sizeof zoom, "*%.6f -1", -std::log2(std::max(1.0, span_ps / kZoomScale)));
  o += "[timestart] " + std::to_string(first_ * 1000) + "\n";
  o += "[size] 1200 800\n[pos] -1 -1\n";
  o += std::string(zoom) + "\n";
  const std::vector<std::string> scopes = ordered_scopes();
  o += "[treeopen] " + top + ".\n";
  for (const auto& sc : scopes) {  // every scope and its parents, expanded in the tree
    for (size_t dot = sc.find('.'); dot != std::string::npos; dot = sc.find('.', dot + 1))
      o += "[treeopen] " + top + "." + sc.substr(0, dot) + ".\n";
    o += "[treeopen] " + top + "." + sc + ".\n";
  }
  o += "[sst_width] 240\n[signals_width] 240\n[sst_expanded] 1\n[sst_vpaned_height] 200\n";
  // Trace flags (GTKWave's, hex): 28 a bit or a string as text, 420 an
  // integer in decimal, 200 a comment line naming the scope below it.
  o += "@28\n" + top + ".clk\n@420\n" + top + ".cycle\n";
  for (const auto& sc : scopes) {
    o += "@200\n-" + sc + "\n";
    for (const auto& s : signals_)
      if (s.scope == sc)
        o += std::string(s.kind == Signal::Kind::kState ? "@28\n" : "@420\n") + top + "." + sc + "." + s.name + "\n";
  }
  return o;
}

uint64_t Waveform::last_shown(uint64_t end) const { return end == 0 ? first_ - 1 : std::min(last_, end - 1); }

void Waveform::write_vcd(const std::string& top, const std::string& comment, uint64_t end,
                         const std::function<void(std::string_view)>& out) const {
  std::string o;
  auto flush = [&](bool force) {
    if (force || o.size() >= kChargeStep) {
      out(o);
      o.clear();
    }
  };
  o += "$comment\n  " + comment + "\n$end\n";
  // Ten 100 ps time units per clock cycle: the clock rises at 10c (every
  // signal changes there) and falls at 10c + 5. A cycle is 1 ns, so GTKWave's
  // ns are cycle numbers (the comment says so).
  o += "$timescale 100 ps $end\n";
  o += "$scope module " + top + " $end\n";
  o += "$var wire 1 " + vcd_id(kClk) + " clk $end\n";
  o += "$var integer 64 " + vcd_id(kCycle) + " cycle $end\n";
  const std::vector<std::string> scopes = ordered_scopes();
  std::vector<std::string> open;  // the scopes open now, outermost first
  auto enter = [&](const std::string& scope) {
    std::vector<std::string> path;
    for (size_t a = 0, b; a <= scope.size(); a = b + 1) {
      b = std::min(scope.find('.', a), scope.size());
      path.push_back(scope.substr(a, b - a));
    }
    size_t common = 0;
    while (common < open.size() && common < path.size() && open[common] == path[common]) ++common;
    for (; open.size() > common; open.pop_back()) o += "$upscope $end\n";
    for (; open.size() < path.size(); open.push_back(path[open.size()]))
      o += "$scope module " + path[open.size()] + " $end\n";
  };
  for (const auto& sc : scopes) {
    enter(sc);
    for (size_t i = 0; i < signals_.size(); ++i) {
      const Signal& s = signals_[i];
      if (s.scope != sc) continue;
      const char* type = s.kind == Signal::Kind::kState ? "string 1 " : "integer 64 ";
      o += std::string("$var ") + type + vcd_id(i + kFirstSignal) + " " + s.name + " $end\n";
    }
  }
  for (; !open.empty(); open.pop_back()) o += "$upscope $end\n";
  o += "$upscope $end\n$enddefinitions $end\n";

  const uint64_t last = last_shown(end);
  if (end == 0 || last < first_) {
    flush(true);
    return;
  }
  std::vector<Cursor> cur;
  cur.reserve(signals_.size());
  for (const auto& s : signals_) cur.emplace_back(s, first_);
  auto put = [&](size_t i) {
    const Signal& s = signals_[i];
    const uint64_t v = cur[i].value;
    if (s.kind == Signal::Kind::kState) {
      o += 's';
      o += v < s.states.size() ? s.states[v] : std::string("?");
    } else {
      put_binary(o, v);
    }
    o += ' ';
    o += vcd_id(i + kFirstSignal);
    o += '\n';
  };
  // The window's first cycle: every signal's value.
  const std::string clk = vcd_id(kClk), cycle = " " + vcd_id(kCycle) + "\n";
  auto falling = [&](uint64_t c) { o += "#" + std::to_string(kUnitsPerCycle * c + kFall) + "\n0" + clk + "\n"; };
  o += "#" + std::to_string(kUnitsPerCycle * first_) + "\n$dumpvars\n1" + clk + "\n";
  put_binary(o, first_);
  o += cycle;
  for (size_t i = 0; i < cur.size(); ++i) put(i);
  o += "$end\n";
  falling(first_);
  // Then every cycle (the counter changes at each), with the signals that change.
  using Next = std::pair<uint64_t, size_t>;  // (cycle of the next event, signal)
  std::priority_queue<Next, std::vector<Next>, std::greater<Next>> heap;
  for (size_t i = 0; i < cur.size(); ++i)
    if (cur[i].next_t() <= last) heap.emplace(cur[i].next_t(), i);
  for (uint64_t c = first_ + 1; c <= last; ++c) {
    o += "#" + std::to_string(kUnitsPerCycle * c) + "\n1" + clk + "\n";
    put_binary(o, c);
    o += cycle;
    while (!heap.empty() && heap.top().first == c) {
      const size_t i = heap.top().second;
      heap.pop();
      const uint64_t was = cur[i].value;
      cur[i].advance();
      if (cur[i].value != was) put(i);
      if (cur[i].next_t() <= last) heap.emplace(cur[i].next_t(), i);
    }
    falling(c);
    flush(false);
  }
  flush(true);
}

}  // namespace ropsim
