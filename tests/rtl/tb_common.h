// Shared harness of the Verilator testbenches (docs/rtl.md): the parameter
// set of a model, the clock, access to bit fields of Verilator's ports (wide
// ports are VlWide word arrays), the $readmemh vector files ropsim writes,
// and a pipelined checker that compares every output bit against the C++
// rule (rtl_models/algo) the golden model calls.
#pragma once
#include <unistd.h>
#include <verilated.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "rtl_models/algo/random_hash.h"

namespace rtl_tb {

/// A mismatch or a broken expectation: the message says what and where.
struct Failure : std::runtime_error {
  using std::runtime_error::runtime_error;
};
/// An output bit that differs from the C++ rule (what the mutation test expects).
struct Mismatch : Failure {
  using Failure::Failure;
};

/// The SystemVerilog parameters a model was verilated with (from CMake).
struct Params {
  std::map<std::string, int> values;
  int operator[](const std::string& k) const {
    auto it = values.find(k);
    if (it == values.end()) throw Failure("parameter " + k + " missing from the model's parameter set");
    return it->second;
  }
  std::string str() const {
    std::string s;
    for (const auto& [k, v] : values) s += (s.empty() ? "" : " ") + k + "=" + std::to_string(v);
    return s;
  }
};

/// What a run does: the ropsim binary that writes the vectors, how many
/// vectors and random inputs, where to put files.
struct Options {
  std::string ropsim;
  std::string work_dir = ".";
  uint64_t vectors = 2000;
  uint64_t random = 1000000;
  uint64_t seed = 1;
};

/// Deterministic random numbers (splitmix64 over a counter).
class Rng {
 public:
  explicit Rng(uint64_t seed) : s_(ropsim::mix64(seed ^ 0x5EED5EEDull)) {}
  uint64_t u64() { return ropsim::mix64(s_++); }
  uint32_t below(uint32_t n) { return uint32_t((u64() >> 32) * n >> 32); }
  uint64_t bits(int n) { return n >= 64 ? u64() : u64() & ((uint64_t{1} << n) - 1); }

 private:
  uint64_t s_;
};

inline uint64_t mask_of(int w) { return w >= 64 ? ~uint64_t{0} : (uint64_t{1} << w) - 1; }

// Bit fields of ports: narrow ports are integers, wide ones VlWide<N>.
template <class T>
void put(T& port, int lo, int w, uint64_t v) {
  const T m = T(mask_of(w)) << lo;
  port = T((port & ~m) | ((T(v) << lo) & m));
}
template <std::size_t N>
void put(VlWide<N>& port, int lo, int w, uint64_t v) {
  if (lo % 32 == 0 && w == 32) {  // a whole word (depths, 32-bit references)
    port[lo / 32] = uint32_t(v);
    return;
  }
  for (int b = 0; b < w; ++b) {
    const int bit = lo + b;
    const uint32_t m = 1u << (bit % 32);
    if ((v >> b) & 1)
      port[bit / 32] |= m;
    else
      port[bit / 32] &= ~m;
  }
}
template <class T>
uint64_t get(const T& port, int lo, int w) {
  return (uint64_t(port) >> lo) & mask_of(w);
}
template <std::size_t N>
uint64_t get(const VlWide<N>& port, int lo, int w) {
  if (lo % 32 == 0 && w == 32) return port[lo / 32];
  uint64_t v = 0;
  for (int b = 0; b < w; ++b) v |= uint64_t((port[(lo + b) / 32] >> ((lo + b) % 32)) & 1u) << b;
  return v;
}

/// One word of a $readmemh file, with bit-field access (bit 0 = the last
/// hex digit's lowest bit).
class HexWord {
 public:
  explicit HexWord(std::string digits) : d_(std::move(digits)) {}
  uint64_t field(int lo, int w) const {
    uint64_t v = 0;
    for (int b = 0; b < w; ++b) {
      const int bit = lo + b;
      const int pos = int(d_.size()) - 1 - bit / 4;
      if (pos < 0) throw Failure("hex word shorter than its layout");
      const char c = d_[size_t(pos)];
      const int nib = c <= '9' ? c - '0' : (c | 0x20) - 'a' + 10;
      v |= uint64_t((nib >> (bit % 4)) & 1) << b;
    }
    return v;
  }
  int bits() const { return int(d_.size()) * 4; }

 private:
  std::string d_;
};

/// A vector file: its words and its fields' places, read from the file's
/// comment block ("//   [hi:lo] name"), so a testbench names fields, not bits.
struct VectorFile {
  std::vector<HexWord> words;
  std::map<std::string, std::pair<int, int>> fields;  ///< name -> (lo, width of one element)
  int lo(const std::string& f) const { return at(f).first; }
  uint64_t get(size_t k, const std::string& f, int element = 0) const {
    const auto& [l, w] = at(f);
    return words[k].field(l + element * w, w);
  }

 private:
  const std::pair<int, int>& at(const std::string& f) const {
    auto it = fields.find(f);
    if (it == fields.end()) throw Failure("vector file has no field " + f);
    return it->second;
  }
};

/// Runs `ropsim vectors UNIT --format hex ARGS` into the work dir and reads
/// the words back, skipping the comment block as $readmemh does.
inline VectorFile ropsim_vectors(const Options& o, const std::string& unit, const std::string& args,
                                 const std::string& tag) {
  // One file per process: ctest runs the parameter sets in parallel.
  const std::string file = o.work_dir + "/rtl_vectors_" + tag + "_" + std::to_string(getpid()) + ".hex";
  const std::string cmd = "'" + o.ropsim + "' vectors " + unit + " --format hex --count " + std::to_string(o.vectors) +
                          " --seed " + std::to_string(o.seed) + " " + args + " -o '" + file + "' > /dev/null";
  if (std::system(cmd.c_str()) != 0) throw Failure("failed: " + cmd);
  std::ifstream in(file);
  VectorFile v;
  for (std::string line; std::getline(in, line);) {
    if (line.empty()) continue;
    if (line.rfind("//", 0) == 0) {
      int hi = 0, lo = 0, n = 0, w = 0;
      char name[64];
      if (std::sscanf(line.c_str(), "// [%d:%d] %63[a-z_0-9]: %d x %d", &hi, &lo, name, &n, &w) == 5)
        v.fields[name] = {lo, w};
      else if (std::sscanf(line.c_str(), "// [%d:%d] %63[a-z_0-9]", &hi, &lo, name) == 3)
        v.fields[name] = {lo, hi - lo + 1};
      continue;
    }
    v.words.emplace_back(line);
  }
  std::remove(file.c_str());
  if (v.words.size() != o.vectors) throw Failure("expected " + std::to_string(o.vectors) + " vectors in " + file);
  if (v.fields.empty()) throw Failure("no field layout in " + file);
  return v;
}

/// A model with clk, rst, in_valid and out_valid: reset, clocking, and a
/// checker for a pipeline fed one input per cycle (with gaps). drive(item)
/// sets the data inputs; check(item) compares the outputs of that item.
template <class M>
class Pipe {
 public:
  Pipe() : ctx_(std::make_unique<VerilatedContext>()), m_(std::make_unique<M>(ctx_.get())) {
    m_->clk = 0;
    m_->rst = 1;
    m_->in_valid = 0;
    m_->eval();
    tick();
    tick();
    m_->rst = 0;
    m_->eval();
  }
  ~Pipe() { m_->final(); }
  M& m() { return *m_; }
  /// One rising edge.
  void tick() {
    m_->clk = 1;
    m_->eval();
    m_->clk = 0;
    m_->eval();
    ++cycle_;
  }
  uint64_t cycle() const { return cycle_; }

  /// Latency: one input alone, cycles until out_valid (fails after limit).
  uint32_t measure_latency(const std::function<void()>& drive, uint32_t limit = 200) {
    drain(limit);
    drive();
    m_->in_valid = 1;
    m_->eval();
    tick();
    m_->in_valid = 0;
    m_->eval();
    for (uint32_t c = 1; c <= limit; ++c) {
      if (m_->out_valid) return c;
      tick();
    }
    throw Failure("no output within " + std::to_string(limit) + " cycles");
  }

  /// Latency of a fragment that enters over `cycles` consecutive clocks:
  /// cycles from its first input to its last output.
  uint32_t measure_burst(const std::function<void(uint32_t)>& drive, uint32_t cycles, uint32_t limit = 200) {
    drain(limit);
    uint32_t outs = 0;
    for (uint32_t c = 0; c < limit; ++c) {
      if (c < cycles) drive(c);
      m_->in_valid = c < cycles;
      m_->eval();
      tick();
      if (m_->out_valid && ++outs == cycles) return c + 1;
    }
    throw Failure("fragment not out within " + std::to_string(limit) + " cycles");
  }

  /// Streams n items: item k is made by make(k) and driven by drive(item);
  /// a cycle without input now and then (1 in 8). Every output is checked by
  /// check(item, k) in input order; an output without a pending input, or an
  /// input whose output never comes, fails.
  template <class Item>
  void stream(uint64_t n, Rng& rng, const std::function<Item(uint64_t)>& make,
              const std::function<void(const Item&)>& drive, const std::function<void(const Item&, uint64_t)>& check) {
    drain(200);
    std::deque<std::pair<Item, uint64_t>> pending;
    uint64_t k = 0;
    uint64_t idle = 0;
    while (k < n || !pending.empty()) {
      const bool feed = k < n && rng.below(8) != 0;
      if (feed) {
        Item it = make(k);
        drive(it);
        pending.emplace_back(std::move(it), k++);
      }
      m_->in_valid = feed;
      m_->eval();
      tick();
      if (m_->out_valid) {
        if (pending.empty()) throw Failure("out_valid with no input in flight at cycle " + std::to_string(cycle_));
        check(pending.front().first, pending.front().second);
        pending.pop_front();
        idle = 0;
      } else if (k >= n && ++idle > 200) {
        throw Failure(std::to_string(pending.size()) + " inputs never came out");
      }
    }
    m_->in_valid = 0;
    m_->eval();
  }

 private:
  void drain(uint32_t limit) {
    m_->in_valid = 0;
    m_->eval();
    for (uint32_t c = 0; c < limit; ++c) tick();
    if (m_->out_valid) throw Failure("out_valid without input");
  }
  std::unique_ptr<VerilatedContext> ctx_;
  std::unique_ptr<M> m_;
  uint64_t cycle_ = 0;
};

/// The hex string of a value, for messages.
inline std::string hex(uint64_t v) {
  char b[20];
  std::snprintf(b, sizeof b, "%llx", static_cast<unsigned long long>(v));
  return b;
}

/// Fails with a message naming the item when got != want.
inline void expect_eq(uint64_t got, uint64_t want, const std::string& what, uint64_t item) {
  if (got != want)
    throw Mismatch(what + " of input " + std::to_string(item) + ": RTL 0x" + hex(got) + ", C++ 0x" + hex(want));
}

/// A test's summary line.
struct Report {
  uint64_t vectors = 0, random = 0;
  uint32_t latency = 0, expected_latency = 0;
};

}  // namespace rtl_tb
