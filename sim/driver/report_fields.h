// Report fields declared where they are written: every JSON field of a report
// is put with its unit and one-line meaning, so the printer is the one
// declaration of the report. Run with a FieldSink, the same printer lists the
// fields (docs/reports.md is generated that way: `ropsim report-fields
// --markdown`, and a test keeps them equal).
#pragma once
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <vector>

#include "counters.h"

namespace ropsim {

struct FieldDoc {
  std::string path;  ///< e.g. timing.units[].cycles.busy
  std::string unit;
  std::string meaning;
};

/// Collects each field's description once, in the order first written.
class FieldSink {
 public:
  void add(const std::string& path, const std::string& unit, const std::string& meaning) {
    if (seen_.insert(path).second) docs_.push_back(FieldDoc{path, unit, meaning});
  }
  const std::vector<FieldDoc>& docs() const { return docs_; }

 private:
  std::vector<FieldDoc> docs_;
  std::set<std::string> seen_;
};

/// A JSON object being written, and where its fields' descriptions go.
class Fields {
 public:
  Fields(nlohmann::ordered_json& node, FieldSink* sink, std::string path = "")
      : node_(node), sink_(sink), path_(std::move(path)) {
    if (!node_.is_object()) node_ = nlohmann::ordered_json::object();
  }
  /// Writes one field with its unit ("-" for none) and meaning.
  template <class T>
  Fields& put(const std::string& key, const T& value, const std::string& unit, const std::string& meaning) {
    node_[key] = value;
    if (sink_) sink_->add(at(key), unit, meaning);
    return *this;
  }
  /// A nested object.
  Fields obj(const std::string& key) { return Fields(node_[key], sink_, at(key)); }
  /// A new object appended to the array `key`.
  Fields item(const std::string& key) {
    nlohmann::ordered_json& a = node_[key];
    if (!a.is_array()) a = nlohmann::ordered_json::array();
    a.push_back(nlohmann::ordered_json::object());
    return Fields(a.back(), sink_, at(key) + "[]");
  }
  /// An empty array `key` (no element written yet).
  void empty_array(const std::string& key) {
    if (!node_.contains(key)) node_[key] = nlohmann::ordered_json::array();
  }
  nlohmann::ordered_json& json() { return node_; }

 private:
  std::string at(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }
  nlohmann::ordered_json& node_;
  FieldSink* sink_;
  std::string path_;
};

/// Every counter whose scope the run's method has (counters.h: every
/// method's, the blend passes' for methods with blend passes, slab's for
/// slab), and the derived sums. With no method, every counter.
inline void put_counters(Fields f, const Counters& c, bool with_blend = true, bool with_slab = true) {
  size_t i = 0;
  c.for_each([&](const char* name, uint64_t v) {
    const StatDesc& d = counter_descs()[i++];
    const bool shown = d.scope == CounterScope::kAll || (d.scope == CounterScope::kBlend && with_blend) ||
                       (d.scope == CounterScope::kSlab && with_slab);
    if (shown) f.put(name, v, d.unit, d.meaning);
  });
  f.put("state_bytes_read", c.state_bytes_read(), "bytes",
        "per-pixel state read: depth, tracker, render targets and slab's layers");
  f.put("state_bytes_written", c.state_bytes_written(), "bytes",
        "per-pixel state written: depth, colour, tracker, render targets and slab's layers");
}

/// The fields as a Markdown table (field, unit, meaning).
inline std::string fields_markdown(const std::vector<FieldDoc>& docs) {
  std::string s = "| field | unit | meaning |\n|---|---|---|\n";
  for (const auto& d : docs) s += "| `" + d.path + "` | " + d.unit + " | " + d.meaning + " |\n";
  return s;
}

}  // namespace ropsim
