#include "rtl_models/config/hw_config.h"

#include <toml++/toml.h>

#include <charconv>
#include <cmath>
#include <cstdio>
#include <functional>
#include <initializer_list>
#include <iterator>
#include <sstream>
#include <system_error>
#include <utility>

#include "rtl_models/algo/bits.h"
#include "rtl_models/config/hw_param_table.h"
#include "util/errors.h"
#include "util/toml_guard.h"

namespace ropsim {

using namespace hw_detail;

const char* to_string(SorterKind k) {
  switch (k) {
    case SorterKind::kBitonic:
      return "bitonic";
    case SorterKind::kRank:
      return "rank";
    case SorterKind::kSerial:
      return "serial";
  }
  return "?";
}
const char* to_string(Interleave k) { return k == Interleave::kDiagonal ? "diagonal" : "row"; }

namespace {

// A design file over the defaults, each key checked on its own.
HwConfig read_hw_text(const std::string& text, const std::string& path) {
  HwConfig c;
  c.name = path;
  const TomlInput in = toml_input(text, path);
  if (!in.error.empty()) throw ConfigError(in.error);
  toml::table doc;
  try {
    doc = toml::parse(in.ascii, path);
  } catch (const toml::parse_error& e) {
    std::ostringstream os;
    os << path << ":" << e.source().begin.line << ": " << e.description();
    throw ConfigError(os.str());
  }
  for (auto&& [sec, node] : doc) {
    const std::string s(sec.str());
    const toml::table* t = node.as_table();
    bool known = false;
    for (const auto& p : params()) known |= section_of(p.key) == s;
    if (!known) fail(path, s, "unknown section");
    if (!t) fail(path, s, "must be a table [" + s + "]");
    for (auto&& [k, v] : *t) {
      const std::string key = s + "." + std::string(k.str());
      const Param* p = find_param(key);
      if (!p) fail(path, key, "unknown key");
      const std::string at = path + ": " + key;
      switch (p->kind) {
        case Kind::kU32:
        case Kind::kInt:
          if (!v.is_integer()) fail(path, key, "must be an integer");
          set_u32(*p, c, v.as_integer()->get(), at);
          break;
        case Kind::kReal:
          if (v.is_integer())
            set_real(*p, c, double(v.as_integer()->get()), at);
          else if (v.is_floating_point())
            set_real(*p, c, v.as_floating_point()->get(), at);
          else
            fail(path, key, "must be a number");
          break;
        case Kind::kBool:
          if (!v.is_boolean()) fail(path, key, "must be true or false");
          *static_cast<bool*>(p->field(c)) = v.as_boolean()->get();
          break;
        case Kind::kSorter:
        case Kind::kInterleave:
        case Kind::kTransFormat:
        case Kind::kAccumFormat:
        case Kind::kDepthEncoder:
          if (!v.is_string()) fail(path, key, "must be a string (" + range_of(*p) + ")");
          set_name(*p, c, v.as_string()->get(), at);
          break;
      }
    }
  }
  return c;
}

HwConfig read_hw_file(const std::string& path) {
  std::string text;
  if (!read_text_file(path, text)) throw ConfigError(path + ": cannot read the design file");
  return read_hw_text(text, path);
}

}  // namespace

HwConfig parse_hw_config(const std::string& text, const std::string& name, const std::vector<std::string>& overrides) {
  HwConfig c = read_hw_text(text, name);
  for (const auto& a : overrides) apply_hw_override(c, a);
  validate_hw_config(c);
  if (!overrides.empty()) c.name += " with --hw-set";
  return c;
}

HwConfig load_hw_config(const std::string& path) {
  HwConfig c = read_hw_file(path);
  validate_hw_config(c);
  return c;
}

HwConfig resolve_hw_config(const std::string& path, const std::vector<std::string>& overrides) {
  HwConfig c = path.empty() ? HwConfig{} : read_hw_file(path);
  for (const auto& a : overrides) apply_hw_override(c, a);
  validate_hw_config(c);
  if (!overrides.empty()) c.name += " with --hw-set";
  return c;
}

void apply_hw_override(HwConfig& cfg, const std::string& a) {
  const std::string at = "--hw-set " + a;
  const auto eq = a.find('=');
  if (eq == std::string::npos) fail_at(at, "expected section.key=value");
  const std::string key = a.substr(0, eq), val = a.substr(eq + 1);
  const Param* p = find_param(key);
  if (!p) fail_at(at, "unknown key " + key);
  // The whole text must be the number: no spaces, no sign '+', no suffix.
  const char* const first = val.data();
  const char* const last = val.data() + val.size();
  HwConfig c = cfg;  // applied to cfg only once accepted
  switch (p->kind) {
    case Kind::kU32:
    case Kind::kInt: {
      long long v = 0;
      const auto r = std::from_chars(first, last, v);
      if (r.ec == std::errc::result_out_of_range) fail_at(at, "value out of range (" + range_of(*p) + ")");
      if (r.ec != std::errc() || r.ptr != last) fail_at(at, "\"" + val + "\" is not an integer");
      set_u32(*p, c, v, at);
      break;
    }
    case Kind::kReal: {
      double v = 0;
      const auto r = std::from_chars(first, last, v);
      if (r.ec == std::errc::result_out_of_range) fail_at(at, "value out of range (" + range_of(*p) + ")");
      if (r.ec != std::errc() || r.ptr != last) fail_at(at, "\"" + val + "\" is not a number");
      set_real(*p, c, v, at);
      break;
    }
    case Kind::kBool:
      if (val != "true" && val != "false") fail_at(at, "must be true or false");
      *static_cast<bool*>(p->field(c)) = val == "true";
      break;
    default:
      set_name(*p, c, val, at);
  }
  c.overrides.push_back(a);
  cfg = std::move(c);
}

namespace {

/// Where a constraint over `keys` was broken: the overrides that set any of
/// them ("--hw-set a, --hw-set b"), or else the file (or the defaults).
std::string origin_of(const HwConfig& c, std::initializer_list<const char*> keys) {
  std::string w;
  for (const auto& a : c.overrides) {
    const std::string key = a.substr(0, a.find('='));
    for (const char* k : keys)
      if (key == k) {
        w += (w.empty() ? "--hw-set " : ", --hw-set ") + a;
        break;
      }
  }
  return w.empty() ? c.name : w;
}

}  // namespace

void validate_hw_config(const HwConfig& c) {
  const auto n = [](uint64_t v) { return std::to_string(v); };
  const uint64_t size = c.cache.size_bytes, line = c.cache.line_bytes, ways = c.cache.ways;
  const uint64_t set_bytes = line * ways;
  if (size < set_bytes)
    fail_at(origin_of(c, {"cache.size_bytes", "cache.line_bytes", "cache.ways"}),
            "cache.size_bytes " + n(size) + " is smaller than one set (cache.line_bytes x cache.ways = " + n(line) +
                " x " + n(ways) + " = " + n(set_bytes) + ")");
  if (size % set_bytes != 0 || !is_pow2(size / set_bytes))
    fail_at(origin_of(c, {"cache.size_bytes", "cache.line_bytes", "cache.ways"}),
            "cache.size_bytes / (cache.line_bytes x cache.ways) = " + n(size) + " / (" + n(line) + " x " + n(ways) +
                ") must be a power-of-two number of sets");
  if (c.dram.row_bytes < line)
    fail_at(origin_of(c, {"dram.row_bytes", "cache.line_bytes"}),
            "dram.row_bytes " + n(c.dram.row_bytes) + " is smaller than cache.line_bytes " + n(line));
  if (c.dram.interleave_bytes < line)
    fail_at(origin_of(c, {"dram.interleave_bytes", "cache.line_bytes"}),
            "dram.interleave_bytes " + n(c.dram.interleave_bytes) + " is smaller than cache.line_bytes " + n(line) +
                " (a line must not span channels)");
}

std::string hw_config_to_toml(const HwConfig& cfg) {
  HwConfig c = cfg, def;
  std::ostringstream os;
  std::string sec;
  for (const auto& p : params()) {
    const std::string key(p.key), s = section_of(key);
    if (s != sec) {
      os << (sec.empty() ? "" : "\n") << "[" << s << "]\n";
      sec = s;
    }
    const std::string v = value_to_string(p, c);
    os << key.substr(s.size() + 1) << " = " << v << "  # " << p.unit << ": " << p.meaning;
    // A default value says what it rests on (a changed one is the file's to explain).
    if (v == value_to_string(p, def)) os << " [" << basis_of(p.key) << "]";
    os << "\n";
  }
  return os.str();
}

void for_each_hw_value(const HwConfig& cfg, const std::function<void(const ParamInfo&, const HwValue&)>& fn) {
  HwConfig c = cfg;
  const auto& info = hw_params();
  for (size_t i = 0; i < params().size(); ++i) {
    const Param& p = params()[i];
    void* f = p.field(c);
    HwValue v;
    switch (p.kind) {
      case Kind::kU32:
        v = int64_t(*static_cast<uint32_t*>(f));
        break;
      case Kind::kInt:
        v = int64_t(*static_cast<int*>(f));
        break;
      case Kind::kReal:
        v = *static_cast<double*>(f);
        break;
      case Kind::kBool:
        v = *static_cast<bool*>(f);
        break;
      case Kind::kSorter:
        v = std::string(to_string(*static_cast<SorterKind*>(f)));
        break;
      case Kind::kInterleave:
        v = std::string(to_string(*static_cast<Interleave*>(f)));
        break;
      case Kind::kDepthEncoder:
        v = std::string(to_string(*static_cast<DepthEncoder*>(f)));
        break;
      case Kind::kTransFormat:
      case Kind::kAccumFormat:
        v = std::string(to_string(*static_cast<TargetFormat*>(f)));
        break;
    }
    fn(info[i], v);
  }
}

uint64_t hw_config_digest(const HwConfig& cfg) {
  HwConfig c = cfg;
  uint64_t h = 0xcbf29ce484222325ull;  // FNV-1a 64
  for (const auto& p : params())
    for (const char ch : std::string(p.key) + "=" + value_to_string(p, c) + "\n") {
      h ^= uint8_t(ch);
      h *= 0x100000001b3ull;
    }
  return h;
}

std::string hw_digest_hex(const HwConfig& cfg) {
  const uint64_t h = hw_config_digest(cfg);
  char buf[9];
  std::snprintf(buf, sizeof buf, "%08x", unsigned((h >> 32) ^ (h & 0xffffffffu)));
  return buf;
}

}  // namespace ropsim
