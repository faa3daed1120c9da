#include "traces/capture/mesh_loader.h"

#include <assimp/GltfMaterial.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <algorithm>
#include <assimp/Importer.hpp>
#include <cmath>
#include <filesystem>
#include <functional>
#include <map>

#include "traces/capture/scene_file.h"

namespace ropsim {

namespace {

MeshMaterial read_material(const aiMaterial* m) {
  MeshMaterial out;
  aiString name;
  if (m->Get(AI_MATKEY_NAME, name) == AI_SUCCESS) out.name = name.C_Str();
  aiColor4D c;
  if (m->Get(AI_MATKEY_BASE_COLOR, c) == AI_SUCCESS) {
    out.base = {c.r, c.g, c.b, c.a};
  } else if (m->Get(AI_MATKEY_COLOR_DIFFUSE, c) == AI_SUCCESS) {
    out.base = {c.r, c.g, c.b, 1.0f};
    float op = 1.0f;
    if (m->Get(AI_MATKEY_OPACITY, op) == AI_SUCCESS) out.base[3] = op;
  }
  aiString mode;
  if (m->Get(AI_MATKEY_GLTF_ALPHAMODE, mode) == AI_SUCCESS) {
    const std::string s = mode.C_Str();
    out.alpha_mode = s == "BLEND" ? AlphaMode::kBlend : s == "MASK" ? AlphaMode::kMask : AlphaMode::kOpaque;
  } else if (out.base[3] < 1.0f) {
    out.alpha_mode = AlphaMode::kBlend;  // OBJ "d" / "Tr"
  }
  float cutoff = 0.5f;
  if (m->Get(AI_MATKEY_GLTF_ALPHACUTOFF, cutoff) == AI_SUCCESS) out.alpha_cutoff = cutoff;
  for (float& x : out.base) x = std::isfinite(x) ? std::clamp(x, 0.0f, x) : 1.0f;
  out.base[3] = std::min(out.base[3], 1.0f);
  return out;
}

int load_material_texture(const aiScene* sc, const aiMaterial* m, const std::string& mesh_path, LoadedMesh& out,
                          std::map<std::string, int>& cache) {
  aiString tp;
  if (m->GetTexture(aiTextureType_BASE_COLOR, 0, &tp) != AI_SUCCESS &&
      m->GetTexture(aiTextureType_DIFFUSE, 0, &tp) != AI_SUCCESS)
    return -1;
  const std::string key = tp.C_Str();
  if (auto it = cache.find(key); it != cache.end()) return it->second;
  Texture t;
  const std::string name = mesh_path + ": texture " + key;
  if (const aiTexture* et = sc->GetEmbeddedTexture(key.c_str())) {
    if (et->mHeight == 0) {
      t = load_texture_memory(et->pcData, et->mWidth, et->achFormatHint, name);
    } else {  // raw BGRA8 texels
      t.name = name;
      t.width = int(et->mWidth);
      t.height = int(et->mHeight);
      for (size_t i = 0; i < size_t(et->mWidth) * et->mHeight; ++i) {
        const aiTexel& x = et->pcData[i];
        t.rgba.insert(t.rgba.end(), {x.r / 255.0f, x.g / 255.0f, x.b / 255.0f, x.a / 255.0f});
      }
    }
  } else {
    const auto file = std::filesystem::path(mesh_path).parent_path() / key;
    std::error_code ec;
    if (!std::filesystem::is_regular_file(file, ec))
      throw CaptureError(mesh_path + ": texture " + key + " not found (looked for " + file.string() + ")");
    t = load_texture_file(file.string());
  }
  out.textures.push_back(std::move(t));
  cache[key] = int(out.textures.size() - 1);
  return cache[key];
}

}  // namespace

namespace {
bool has_uvs(const aiScene* sc) {
  for (unsigned i = 0; i < sc->mNumMeshes; ++i)
    if (sc->mMeshes[i]->HasTextureCoords(0)) return true;
  return false;
}
}  // namespace

LoadedMesh load_mesh(const std::string& path, bool points_ok, bool textures) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw CaptureError(path + ": no such mesh file (set --mesh-dir or ROPSIM_MESH_DIR to the folder of the meshes)");
  Assimp::Importer imp;
  // Triangulate polygons; keep points (point clouds) and lines (dropped below).
  // (ValidateDataStructure rejects point clouds, which have no faces.)
  const unsigned flags =
      aiProcess_Triangulate | aiProcess_GenSmoothNormals | (points_ok ? 0u : unsigned(aiProcess_ValidateDataStructure));
  const aiScene* sc = imp.ReadFile(path, flags);
  if (!sc || (sc->mFlags & AI_SCENE_FLAGS_INCOMPLETE) || !sc->mRootNode)
    throw CaptureError(path + ": cannot load the mesh: " + std::string(imp.GetErrorString()));

  LoadedMesh out;
  out.path = path;
  std::map<std::string, int> texture_cache;
  for (unsigned i = 0; i < sc->mNumMaterials; ++i) {
    out.materials.push_back(read_material(sc->mMaterials[i]));
    if (textures) out.materials.back().texture = load_material_texture(sc, sc->mMaterials[i], path, out, texture_cache);
  }
  const bool any_uvs = has_uvs(sc);
  if (out.materials.empty()) out.materials.push_back(MeshMaterial{});
  bool any_colors = false;
  for (unsigned i = 0; i < sc->mNumMeshes; ++i) any_colors |= sc->mMeshes[i]->HasVertexColors(0);

  // Flatten the node hierarchy: each mesh instance in depth-first node order.
  std::function<void(const aiNode*, const aiMatrix4x4&)> walk = [&](const aiNode* node, const aiMatrix4x4& parent) {
    const aiMatrix4x4 m = parent * node->mTransformation;
    aiMatrix3x3 nm(m);
    nm.Inverse().Transpose();
    for (unsigned k = 0; k < node->mNumMeshes; ++k) {
      const aiMesh* mesh = sc->mMeshes[node->mMeshes[k]];
      const uint32_t base = uint32_t(out.positions.size());
      for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
        const aiVector3D p = m * mesh->mVertices[v];
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
          throw CaptureError(path + ": mesh " + std::to_string(node->mMeshes[k]) + " vertex " + std::to_string(v) +
                             " is not finite (NaN or infinity)");
        out.positions.push_back({p.x, p.y, p.z});
        std::array<double, 3> n{0, 0, 0};
        if (mesh->HasNormals()) {
          aiVector3D q = nm * mesh->mNormals[v];
          const double len = std::sqrt(double(q.x) * q.x + double(q.y) * q.y + double(q.z) * q.z);
          if (len > 0 && std::isfinite(len)) n = {q.x / len, q.y / len, q.z / len};
        }
        out.normals.push_back(n);
        if (any_uvs) {
          const aiVector3D uv = mesh->HasTextureCoords(0) ? mesh->mTextureCoords[0][v] : aiVector3D(0, 0, 0);
          out.uvs.push_back({std::isfinite(uv.x) ? uv.x : 0.0f, std::isfinite(uv.y) ? uv.y : 0.0f});
        }
        if (any_colors) {
          if (mesh->HasVertexColors(0)) {
            const aiColor4D c = mesh->mColors[0][v];
            out.colors.push_back({c.r, c.g, c.b, c.a});
          } else {
            out.colors.push_back({1, 1, 1, 1});
          }
        }
      }
      if (mesh->mNumFaces == 0)  // a point cloud without faces (PLY)
        for (unsigned v = 0; v < mesh->mNumVertices; ++v) out.points.push_back(base + v);
      for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
        const aiFace& face = mesh->mFaces[f];
        if (face.mNumIndices == 3) {
          out.triangles.push_back({base + face.mIndices[0], base + face.mIndices[1], base + face.mIndices[2]});
          out.triangle_material.push_back(std::min<uint32_t>(mesh->mMaterialIndex, uint32_t(out.materials.size() - 1)));
        } else if (face.mNumIndices == 1) {
          out.points.push_back(base + face.mIndices[0]);
        }
      }
    }
    for (unsigned c = 0; c < node->mNumChildren; ++c) walk(node->mChildren[c], m);
  };
  walk(sc->mRootNode, aiMatrix4x4());
  if (out.triangles.empty() && !(points_ok && !out.points.empty()))
    throw CaptureError(path +
                       (points_ok ? ": the mesh has no points and no triangles" : ": the mesh has no triangles"));
  return out;
}

}  // namespace ropsim
