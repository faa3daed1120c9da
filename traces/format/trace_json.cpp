// JSON views of trace headers and fragments (`ropsim trace info|dump`).
#include <nlohmann/json.hpp>

#include "trace.h"

namespace ropsim {

std::string header_to_json(const TraceHeader& h) {
  nlohmann::ordered_json j;
  j["format"] = "ropsim-trace";
  j["version"] = kTraceVersion;
  j["scene"] = h.scene_name;
  j["width"] = h.width;
  j["height"] = h.height;
  j["spp"] = h.spp;
  j["depth_mode"] = to_string(h.depth_mode);
  j["color_format"] = to_string(h.color_format);
  j["compression"] = to_string(h.compression);
  j["checksummed"] = h.checksummed;
  j["clear_color"] = h.clear_color;
  j["clear_depth"] = h.clear_depth;
  auto pos = nlohmann::json::array();
  for (int i = 0; i < h.spp; ++i) pos.push_back({h.positions[i].x, h.positions[i].y});
  j["sample_positions_256ths"] = pos;
  return j.dump();
}

std::string fragment_to_json(const TraceHeader& h, const Fragment& f, uint64_t index) {
  nlohmann::ordered_json j;
  j["record"] = index;
  j["draw"] = f.draw_id;
  j["prim"] = f.prim_id;
  j["x"] = f.x;
  j["y"] = f.y;
  char cov[24];
  std::snprintf(cov, sizeof cov, "0x%llx", static_cast<unsigned long long>(f.coverage));
  j["coverage"] = cov;
  if (h.depth_mode == DepthMode::kPlane) {
    j["z0"] = f.z0;
    j["dzdx"] = f.dzdx;
    j["dzdy"] = f.dzdy;
  }
  float z[64];
  fragment_sample_depths(h, f, z);
  // Keyed by the sample's index, in increasing sample order (an ordered
  // object: a plain one would sort the keys as strings, "11" before "2").
  auto zs = nlohmann::ordered_json::object();
  for (uint64_t m = f.coverage; m; m &= m - 1) {
    int i = __builtin_ctzll(m);
    zs[std::to_string(i)] = z[i];
  }
  j["sample_depth"] = zs;
  j["rgb"] = f.rgb;
  j["alpha"] = f.alpha;
  return j.dump();
}

}  // namespace ropsim
