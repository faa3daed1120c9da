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

#include "rtl_models/functional/compressibility.h"
#include "rtl_models/functional/counters.h"

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

/// The compressibility of the final buffers (compressibility.h) under the
/// design's [compression] format (a functional run with --compressibility):
/// the format, then one entry per compressed surface.
inline void put_compressibility(Fields f, const CompressionStats& cs, const CompressionSetup& setup) {
  const CompressionFormat& fm = setup.format;
  f.put("depth", setup.depth, "-", "--compressibility: compression.depth, depth plane compression on");
  f.put("color", setup.color, "-", "compression.color: MSAA colour compression on (colour and blend targets)");
  f.put("tile_pixels", fm.tile_pixels, "pixels", "pixels of a memory tile (all their samples)");
  f.put("size_classes", fm.size_classes, "classes", "block sizes U, U/2, ... a tile is stored in");
  f.put("depth_planes", fm.depth_planes, "planes", "most plane equations in a depth tile");
  f.put("depth_encoder", to_string(fm.depth_encoder), "-",
        "how a depth tile's planes are found: plane (the rasterizer's) or fit (fitted to the depths)");
  f.put("color_k", fm.color_k, "colours", "K, most distinct colours per pixel");
  f.put("metadata_bits", metadata_bits(fm), "bits", "state bits per memory tile");
  f.empty_array("buffers");
  for (int b = 0; b < kBuffers; ++b) {
    if (!cs.compressed[size_t(b)]) continue;
    const BufferCompression& c = cs.buffers[size_t(b)];
    Fields e = f.item("buffers");
    e.put("buffer", to_string(Buffer(b)), "-", "the surface");
    e.put("tiles", c.tiles, "tiles", "memory tiles of the surface over the whole screen");
    e.put("tiles_cleared", c.tiles_cleared, "tiles",
          "tiles holding only the clear value at the end of the frame (fast clear: state bits only)");
    e.put("bytes_uncompressed", c.bytes_uncompressed, "bytes", "the other tiles' bytes uncompressed");
    e.put("bytes_compressed", c.bytes_compressed, "bytes", "the same tiles in their compressed block sizes");
    e.put("ratio", c.bytes_compressed ? double(c.bytes_uncompressed) / double(c.bytes_compressed) : 1.0, "-",
          "bytes_uncompressed / bytes_compressed");
    std::vector<uint64_t> n(c.tiles_per_class.begin(), c.tiles_per_class.begin() + fm.size_classes);
    std::vector<double> share;
    const uint64_t stored = c.tiles - c.tiles_cleared;
    for (uint64_t k : n) share.push_back(stored ? double(k) / double(stored) : 0.0);
    e.put("tiles_per_class", n, "tiles",
          "[j]: written tiles stored in U / 2^j bytes (j = 0: uncompressed, 1: half, 2: quarter, 3: eighth)");
    e.put("class_shares", share, "-", "the same as shares of the written tiles");
    e.put("metadata_bytes", c.metadata_bytes, "bytes", "the surface's state bits, every tile of the screen");
  }
}

/// The fields as a Markdown table (field, unit, meaning).
inline std::string fields_markdown(const std::vector<FieldDoc>& docs) {
  std::string s = "| field | unit | meaning |\n|---|---|---|\n";
  for (const auto& d : docs) s += "| `" + d.path + "` | " + d.unit + " | " + d.meaning + " |\n";
  return s;
}

}  // namespace ropsim
