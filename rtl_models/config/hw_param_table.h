// The design parameters' table: each parameter's key, unit, range, meaning,
// field of HwConfig and the basis of its default, declared once; and the
// typed reads and writes of one parameter that the design file, the
// --hw-set overrides and the reports share (hw_config.cpp).
#pragma once
#include <functional>
#include <string>
#include <vector>

#include "rtl_models/config/hw_config.h"

namespace ropsim::hw_detail {

enum class Kind { kU32, kInt, kReal, kBool, kSorter, kInterleave, kTransFormat, kAccumFormat, kDepthEncoder };

struct Param {
  const char* key;
  const char* unit;
  Kind kind;
  double lo, hi;
  bool pow2;
  const char* meaning;
  std::function<void*(HwConfig&)> field;
};

/// Every parameter, in the order of the design file.
const std::vector<Param>& params();
/// The parameter named key, or nullptr.
const Param* find_param(const std::string& key);
/// A parameter's basis for its default (InternalError: none, or two).
const char* basis_of(const char* key);
/// "clock" of "clock.frequency_ghz".
std::string section_of(const std::string& key);
[[noreturn]] void fail(const std::string& where, const std::string& key, const std::string& what);
/// `at` names the source and key: "FILE: section.key" or "--hw-set section.key=value".
[[noreturn]] void fail_at(const std::string& at, const std::string& what);
/// The shortest decimal that reads back as v (std::to_chars), as a TOML float:
/// 1.23456789 stays 1.23456789, 2 prints as 2.0.
std::string real_to_string(double v);
/// A parameter's value in c as the design file writes it.
std::string value_to_string(const Param& p, HwConfig& c);
/// The values a parameter takes, in words.
std::string range_of(const Param& p);
// Sets one parameter from either a TOML node or a command-line string, after
// checking the value; `at` names the source and key for the error.
void set_u32(const Param& p, HwConfig& c, int64_t v, const std::string& at);
void set_real(const Param& p, HwConfig& c, double v, const std::string& at);
void set_name(const Param& p, HwConfig& c, const std::string& s, const std::string& at);

}  // namespace ropsim::hw_detail
