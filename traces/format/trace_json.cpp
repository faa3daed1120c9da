// JSON views of trace headers and fragments (`ropsim trace info|dump`).
#include <nlohmann/json.hpp>

#include "traces/format/trace.h"

namespace ropsim {

std::string header_to_json(const TraceHeader& h) {
  nlohmann::ordered_json j;
  j["format"] = "ropsim-trace";
  j["version"] = h.version();
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
  // The draw table (version 2), in draw-id order; empty: every draw has
  // default_draw_state().
  auto draws = nlohmann::ordered_json::array();
  for (const DrawState& s : h.draws.states()) draws.push_back(nlohmann::ordered_json::parse(draw_state_to_json(s)));
  j["draws"] = draws;
  return j.dump();
}

std::string draw_state_to_json(const DrawState& s) {
  nlohmann::ordered_json j;
  j["draw"] = s.draw_id;
  j["name"] = s.name;
  j["kind"] = to_string(draw_kind(s));
  j["blend"] = s.blend;
  j["equation_rgb"] = to_string(s.eq_rgb);
  j["equation_alpha"] = to_string(s.eq_alpha);
  j["src_rgb"] = to_string(s.src_rgb);
  j["dst_rgb"] = to_string(s.dst_rgb);
  j["src_alpha"] = to_string(s.src_alpha);
  j["dst_alpha"] = to_string(s.dst_alpha);
  j["blend_color"] = s.blend_color;
  j["depth_test"] = s.depth_test;
  j["depth_func"] = to_string(s.depth_func);
  j["depth_write"] = s.depth_write;
  j["color_mask"] = s.color_mask;
  j["encoding"] = to_string(s.encoding);
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
