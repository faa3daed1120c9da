// A small VCD reader for the waveform tests: the header (comment, timescale,
// scopes and variables) and every value change with its time. Throws
// std::runtime_error on anything it cannot read, so a malformed file fails
// the test that reads it.
#pragma once
#include <cstdint>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace ropsim_test {

struct Vcd {
  struct Var {
    std::string type;   ///< "string", "integer", "wire"...
    std::string scope;  ///< the scopes from the outermost, joined by '.': "top.rop0"
    std::string name;
    int width = 0;
  };
  struct Change {
    uint64_t time;
    size_t var;         ///< index in vars
    std::string value;  ///< a string's text, or a vector's bits ("101")
  };
  std::string comment, timescale;  ///< timescale as written: "100 ps"
  std::vector<Var> vars;
  std::vector<Change> changes;   ///< in file order
  std::vector<uint64_t> stamps;  ///< every "#t" line, in file order

  /// The variable named scope.name, or -1.
  int find(const std::string& scope, const std::string& name) const {
    for (size_t i = 0; i < vars.size(); ++i)
      if (vars[i].scope == scope && vars[i].name == name) return int(i);
    return -1;
  }
  /// A vector value's number ("101" -> 5).
  static uint64_t number(const std::string& bits) {
    uint64_t v = 0;
    for (char c : bits) {
      if (c != '0' && c != '1') throw std::runtime_error("VCD: not a binary value: " + bits);
      v = v * 2 + uint64_t(c - '0');
    }
    return v;
  }
  /// Variable var's value at every time first..last (the value of its last
  /// change at or before each; "" before its first).
  std::vector<std::string> trace(size_t var, uint64_t first, uint64_t last) const {
    std::vector<std::string> v(size_t(last - first + 1));
    std::string now;
    size_t k = 0;
    for (uint64_t t = first; t <= last; ++t) {
      for (; k < changes.size() && changes[k].time <= t; ++k)
        if (changes[k].var == var) now = changes[k].value;
      v[size_t(t - first)] = now;
    }
    return v;
  }
  /// The same at the rising clock edge of every cycle first..last: ropsim's
  /// waveforms have ten time units per cycle, cycle c at time 10c.
  static constexpr uint64_t kUnitsPerCycle = 10;
  std::vector<std::string> trace_cycles(size_t var, uint64_t first, uint64_t last) const {
    const std::vector<std::string> all = trace(var, kUnitsPerCycle * first, kUnitsPerCycle * last);
    std::vector<std::string> v;
    for (size_t i = 0; i < all.size(); i += kUnitsPerCycle) v.push_back(all[i]);
    return v;
  }
};

inline Vcd parse_vcd(const std::string& text) {
  Vcd v;
  std::istringstream in(text);
  std::vector<std::string> scopes;
  std::map<std::string, size_t> ids;
  auto body = [&](std::string& out) {  // the words up to "$end"
    for (std::string w; in >> w;) {
      if (w == "$end") return;
      out += (out.empty() ? "" : " ") + w;
    }
    throw std::runtime_error("VCD: a section without $end");
  };
  for (std::string w;;) {
    if (!(in >> w)) throw std::runtime_error("VCD: no $enddefinitions");
    if (w == "$enddefinitions") {
      std::string rest;
      body(rest);
      break;
    }
    std::string b;
    if (w == "$comment") {
      body(v.comment);
    } else if (w == "$timescale") {
      body(v.timescale);
    } else if (w == "$scope") {
      body(b);
      std::istringstream s(b);
      std::string kind, name;
      s >> kind >> name;
      scopes.push_back(name);
    } else if (w == "$upscope") {
      body(b);
      if (scopes.empty()) throw std::runtime_error("VCD: $upscope outside any scope");
      scopes.pop_back();
    } else if (w == "$var") {
      body(b);
      std::istringstream s(b);
      Vcd::Var var;
      std::string id;
      if (!(s >> var.type >> var.width >> id >> var.name)) throw std::runtime_error("VCD: bad $var " + b);
      for (size_t i = 0; i < scopes.size(); ++i) var.scope += (i ? "." : "") + scopes[i];
      if (!ids.emplace(id, v.vars.size()).second) throw std::runtime_error("VCD: identifier used twice: " + id);
      v.vars.push_back(var);
    } else if (w[0] == '$') {
      body(b);  // $date, $version...
    } else {
      throw std::runtime_error("VCD: unexpected in the header: " + w);
    }
  }
  if (!scopes.empty()) throw std::runtime_error("VCD: a scope is not closed");
  uint64_t now = 0;
  bool timed = false;
  auto var_of = [&](const std::string& id) {
    const auto it = ids.find(id);
    if (it == ids.end()) throw std::runtime_error("VCD: a change of an undeclared identifier " + id);
    if (!timed) throw std::runtime_error("VCD: a change before the first time stamp");
    return it->second;
  };
  for (std::string w; in >> w;) {
    if (w == "$dumpvars" || w == "$end") continue;
    if (w[0] == '#') {
      const uint64_t t = std::stoull(w.substr(1));
      if (timed && t <= now) throw std::runtime_error("VCD: time stamps do not increase at #" + w.substr(1));
      now = t;
      timed = true;
      v.stamps.push_back(t);
    } else if (w[0] == 'b' || w[0] == 's' || w[0] == 'r') {
      std::string id;
      if (!(in >> id)) throw std::runtime_error("VCD: a value without an identifier: " + w);
      v.changes.push_back(Vcd::Change{now, var_of(id), w.substr(1)});
    } else if (w[0] == '0' || w[0] == '1' || w[0] == 'x' || w[0] == 'z') {
      v.changes.push_back(Vcd::Change{now, var_of(w.substr(1)), w.substr(0, 1)});
    } else {
      throw std::runtime_error("VCD: unexpected " + w);
    }
  }
  return v;
}

}  // namespace ropsim_test
