// Loads a mesh file (OBJ, glTF 2.0, PLY, ... anything assimp reads) into one
// flat triangle list in the model's world space (node transforms applied),
// with per-vertex normals, optional vertex colours and per-triangle materials.
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "traces/capture/texture.h"

namespace ropsim {

enum class AlphaMode { kOpaque, kMask, kBlend };

struct MeshMaterial {
  std::string name;
  std::array<float, 4> base{1, 1, 1, 1};      ///< linear RGBA: glTF baseColorFactor, else diffuse colour and opacity
  AlphaMode alpha_mode = AlphaMode::kOpaque;  ///< glTF alphaMode (OPAQUE for other formats)
  float alpha_cutoff = 0.5f;                  ///< glTF alphaCutoff (MASK)
  int texture = -1;  ///< base colour texture (RGBA: colour and alpha), index into LoadedMesh::textures
};

struct LoadedMesh {
  std::string path;
  std::vector<std::array<double, 3>> positions;  ///< world space
  std::vector<std::array<double, 3>> normals;    ///< per vertex, unit length (same count as positions)
  std::vector<std::array<float, 4>> colors;      ///< per vertex RGBA, empty when the file has none
  std::vector<std::array<float, 2>> uvs;         ///< per vertex texture coordinates (set 0), empty when none
  std::vector<Texture> textures;                 ///< loaded only when asked for
  std::vector<std::array<uint32_t, 3>> triangles;
  std::vector<uint32_t> triangle_material;  ///< index into materials, per triangle
  std::vector<uint32_t> points;             ///< vertices used as point primitives (PLY point clouds)
  std::vector<MeshMaterial> materials;
};

/// Loads through assimp. Throws CaptureError naming the file: missing,
/// unreadable, corrupt, no triangles (unless points_ok), or a non-finite
/// vertex. With `textures`, materials' base colour textures (glTF
/// baseColorTexture, OBJ map_Kd; embedded or beside the mesh) are decoded.
LoadedMesh load_mesh(const std::string& path, bool points_ok = false, bool textures = false);

}  // namespace ropsim
