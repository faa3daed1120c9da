// Capture from mesh scene files (docs/capture.md): watertightness through
// the whole pipeline (camera, clipping, snapping), the standard sample
// positions in captured traces, near / far clipping, materials, bad input,
// the command line, and the cross-check against Mesa's llvmpipe.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "rtl_models/algo/random_hash.h"
#include "tests/compare_util.h"
#include "traces/capture/capture.h"
#include "traces/capture/mesh_loader.h"
#include "traces/capture/scene_file.h"
#include "traces/format/trace.h"
#include "traces/raster/sample_patterns.h"
#ifdef ROPSIM_HAVE_OSMESA
#include "traces/capture/mesa_capture.h"
#endif

#ifndef ROPSIM_BINARY
#error "ROPSIM_BINARY must name the built ropsim executable (tests/CMakeLists.txt)"
#endif

using namespace ropsim;
namespace fs = std::filesystem;

namespace {

/// A scratch folder for scene and mesh files, removed afterwards.
class Scratch {
 public:
  Scratch() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    root_ = fs::temp_directory_path() /
            ("ropsim-test-capture-" + std::to_string(::getpid()) + "-" + (info ? std::string(info->name()) : "x"));
    fs::remove_all(root_);
    fs::create_directories(root_);
  }
  ~Scratch() {
    std::error_code ec;
    fs::remove_all(root_, ec);
  }
  std::string write(const std::string& name, const std::string& text) const {
    std::ofstream f(root_ / name, std::ios::binary);
    f << text;
    return (root_ / name).string();
  }
  std::string path(const std::string& name) const { return (root_ / name).string(); }
  std::vector<std::string> files() const {
    std::vector<std::string> v;
    for (const auto& e : fs::directory_iterator(root_)) v.push_back(e.path().filename().string());
    return v;
  }

 private:
  fs::path root_;
};

/// A scene file text around objects, with a camera at `eye` looking at `target`.
std::string scene_text(const std::string& objects, const std::string& camera = "eye = [0, 0, 5]\ntarget = [0, 0, 0]",
                       const std::string& extra = "width = 64\nheight = 48\nspp = 4\n") {
  return extra + "\n[camera]\n" + camera + "\nfov_y = 60\nnear = 1\nfar = 50\n\n" + objects;
}

/// A w x h grid of quads (two triangles each) in the plane z = 0 over
/// [-s, s]^2, interior vertices jittered, diagonals and windings alternating.
std::string grid_obj(int n, double s, uint64_t seed) {
  std::ostringstream o;
  o.precision(17);
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      double x = -s + 2 * s * i / n, y = -s + 2 * s * j / n;
      if (i > 0 && i < n && j > 0 && j < n) {
        const uint64_t k = mix64(seed ^ uint64_t(j * 1000 + i));
        x += (double(k & 0xFFFF) / 65536.0 - 0.5) * s / n;
        y += (double((k >> 16) & 0xFFFF) / 65536.0 - 0.5) * s / n;
      }
      o << "v " << x << " " << y << " 0\n";
    }
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i + 1, b = a + 1, c = a + n + 2, d = a + n + 1;
      if ((i + j) % 2)
        o << "f " << a << " " << b << " " << c << "\nf " << a << " " << d << " " << c << "\n";
      else
        o << "f " << a << " " << b << " " << d << "\nf " << b << " " << c << " " << d << "\n";
    }
  return o.str();
}

/// A grid mesh seen head-on by a camera at (0, 0, 2), fov 90, 64 x 64
/// pixels: world (X, Y, 0) lands exactly on screen (32 + 16 X, 32 - 16 Y).
/// Interior vertices are on the 1/256 pixel grid, every third one exactly
/// on a sample position, so edges run through samples (fill-rule ties).
std::string headon_grid_obj(int spp, uint64_t seed) {
  const auto pos = standard_sample_positions(spp);
  const int G = 9;
  std::ostringstream o;
  o.precision(17);
  for (int j = 0; j <= G; ++j)
    for (int i = 0; i <= G; ++i) {
      const uint64_t k = mix64(seed ^ uint64_t(j * 131 + i));
      double x = -3.0 + 70.0 * i / G, y = -3.0 + 70.0 * j / G;
      if (i > 0 && i < G && j > 0 && j < G) {
        const SamplePos sp = pos[size_t(k % unsigned(spp))];
        x = std::floor(x) + (k % 3 == 0 ? sp.x / 256.0 : double(k % 256) / 256.0);
        y = std::floor(y) + (k % 3 == 0 ? sp.y / 256.0 : double((k >> 8) % 256) / 256.0);
      }
      o << "v " << (x - 32) / 16 << " " << (32 - y) / 16 << " 0\n";
    }
  for (int j = 0; j < G; ++j)
    for (int i = 0; i < G; ++i) {
      const int a = j * (G + 1) + i + 1, b = a + 1, c = a + G + 2, d = a + G + 1;
      if ((i + j) % 2)
        o << "f " << a << " " << b << " " << c << "\nf " << a << " " << d << " " << c << "\n";
      else
        o << "f " << a << " " << b << " " << d << "\nf " << b << " " << c << " " << d << "\n";
    }
  return o.str();
}

std::string base64(const std::string& bytes) {
  static const char* b64 = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string enc;
  for (size_t i = 0; i < bytes.size(); i += 3) {
    const size_t n = std::min<size_t>(3, bytes.size() - i);
    uint32_t v = 0;
    for (size_t k = 0; k < 3; ++k) v = v << 8 | (k < n ? uint8_t(bytes[i + k]) : 0u);
    for (size_t k = 0; k < 4; ++k) enc += k <= n ? b64[(v >> (6 * (3 - k))) & 63] : '=';
  }
  return enc;
}

template <class T>
std::string raw_bytes(const std::vector<T>& v) {
  return std::string(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
}

/// An uncompressed 32-bit TGA (top-left origin), texels as RGBA bytes.
std::string tga(int w, int h, const std::vector<std::array<uint8_t, 4>>& rgba) {
  std::string t(18, '\0');
  t[2] = 2;
  t[12] = char(w & 0xFF);
  t[13] = char(w >> 8);
  t[14] = char(h & 0xFF);
  t[15] = char(h >> 8);
  t[16] = 32;
  t[17] = 0x28;
  for (const auto& p : rgba) t += std::string{char(p[2]), char(p[1]), char(p[0]), char(p[3])};
  return t;
}

std::vector<Fragment> capture_fragments(const SceneSpec& s, CaptureStats* stats = nullptr) {
  const PreparedScene ps = prepare_scene(s);
  std::vector<Fragment> out;
  CaptureStats st = rasterize_prepared(ps, capture_header(s), [&](const Fragment& f) { out.push_back(f); });
  if (stats) *stats = st;
  return out;
}

/// Fragments covering each sample of the screen.
std::vector<int> sample_counts(const SceneSpec& s, const std::vector<Fragment>& frags) {
  std::vector<int> n(size_t(s.width) * s.height * size_t(s.spp), 0);
  for (const auto& f : frags)
    for (uint64_t m = f.coverage; m; m &= m - 1)
      ++n[(size_t(f.y) * s.width + f.x) * size_t(s.spp) + size_t(__builtin_ctzll(m))];
  return n;
}

std::string shared_mesh_dir() {
  if (const char* e = std::getenv("ROPSIM_MESH_DIR"); e && *e) return e;
  return (fs::path(ROPSIM_SOURCE_DIR) / ".." / "shared" / "data" / "meshes").lexically_normal().string();
}

std::string repo_scene(const std::string& name) {
  return (fs::path(ROPSIM_SOURCE_DIR) / "traces" / "scenes" / "mesh" / name).string();
}

struct CliResult {
  int code = -1;
  std::string out, err;
};

CliResult run_cli(const Scratch& box, const std::string& args) {
  const std::string out = box.path("stdout.txt"), err = box.path("stderr.txt");
  const std::string cmd = "'" ROPSIM_BINARY "' " + args + " >'" + out + "' 2>'" + err + "' </dev/null";
  const int st = std::system(cmd.c_str());
  CliResult r;
  r.code = (st != -1 && WIFEXITED(st)) ? WEXITSTATUS(st) : -1;
  std::ifstream fo(out), fe(err);
  std::stringstream so, se;
  so << fo.rdbuf();
  se << fe.rdbuf();
  r.out = so.str();
  r.err = se.str();
  fs::remove(out);
  fs::remove(err);
  return r;
}

/// `ropsim capture SCENE -o out.trace` must fail with one line naming every
/// needle, without a crash and without leaving out.trace (or its temporary .out.trace.XXXXXX).
void expect_capture_error(const Scratch& box, const std::string& scene, const std::vector<std::string>& needles) {
  SCOPED_TRACE("ropsim capture " + scene);
  const CliResult r = run_cli(box, "capture '" + scene + "' -o '" + box.path("out.trace") + "'");
  EXPECT_EQ(r.code, 1) << "expected exit 1 (not a crash)\nstderr: " << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << "stderr must be one line: " << r.err;
  EXPECT_EQ(r.err.rfind("ropsim: error: ", 0), 0u) << r.err;
  for (const auto& n : needles) EXPECT_NE(r.err.find(n), std::string::npos) << "no \"" << n << "\" in: " << r.err;
  EXPECT_FALSE(fs::exists(box.path("out.trace"))) << "a failed capture left its output";
  for (const auto& e : fs::directory_iterator(fs::path(box.path("out.trace")).parent_path()))
    EXPECT_NE(e.path().filename().string().rfind(".out.trace.", 0), 0u) << "a failed capture left " << e.path();
}

}  // namespace

// A mesh of adjacent triangles covering more than the screen, seen through
// the perspective camera, covers every sample exactly once: shared edges
// snap identically and the top-left rule gives each sample to one triangle.
TEST(CaptureWatertight, MeshCoveringTheScreenCoversEverySampleOnce) {
  Scratch box;
  for (int spp : {1, 4, 16, 64}) {
    box.write("grid.obj", grid_obj(23, 4.0, uint64_t(spp)));
    const std::string scene =
        box.write("s.toml", scene_text("[[object]]\nmesh = \"grid.obj\"\nopacity = 0.5\norder = \"shuffled\"\n",
                                       "eye = [0.3, -0.2, 3]\ntarget = [0, 0, 0]\nup = [0.1, 1, 0]",
                                       "width = 61\nheight = 47\nspp = " + std::to_string(spp) + "\n"));
    const SceneSpec s = load_scene_file(scene);
    const auto frags = capture_fragments(s);
    const auto n = sample_counts(s, frags);
    for (size_t i = 0; i < n.size(); ++i)
      ASSERT_EQ(n[i], 1) << spp << " spp: sample " << i % size_t(spp) << " of pixel (" << (i / size_t(spp)) % s.width
                         << ", " << (i / size_t(spp)) / s.width << ") covered " << n[i] << " times";
  }
}

// Head-on, with edges and vertices exactly on sample positions: only the
// top-left rule decides those samples, each must go to exactly one triangle.
TEST(CaptureWatertight, EdgesThroughSamplesCoverEverySampleOnce) {
  Scratch box;
  for (int spp : {1, 2, 4, 8, 16, 32, 64}) {
    box.write("grid.obj", headon_grid_obj(spp, uint64_t(spp) * 77));
    const std::string scene =
        box.write("s.toml", "width = 64\nheight = 64\nspp = " + std::to_string(spp) +
                                "\n[camera]\neye = [0, 0, 2]\ntarget = [0, 0, 0]\nfov_y = 90\nnear = 1\nfar = 3\n"
                                "[[object]]\nmesh = \"grid.obj\"\nopacity = 0.5\n");
    const SceneSpec s = load_scene_file(scene);
    const auto frags = capture_fragments(s);
    const auto n = sample_counts(s, frags);
    for (size_t i = 0; i < n.size(); ++i)
      ASSERT_EQ(n[i], 1) << spp << " spp: sample " << i % size_t(spp) << " of pixel (" << (i / size_t(spp)) % s.width
                         << ", " << (i / size_t(spp)) / s.width << ") covered " << n[i] << " times";
  }
}

// The same with a floor crossing the near and the far plane: the clipped
// polygons stay watertight (no sample twice), the floor covers every sample
// it should up to the far plane and nothing beyond it or above the horizon,
// and every covered sample carries the floor's depth at that sample (D3D
// depth of the view-axis distance d: far / (far - near) * (1 - near / d)),
// in both depth modes of the trace.
TEST(CaptureClipping, FloorThroughNearAndFarPlanesIsWatertight) {
  Scratch box;  // a floor y = 0 from z = +20 (behind the camera) to z = -2000
  box.write("floor.obj", [] {
    std::ostringstream m;
    const int nx = 16, nz = 40;
    for (int j = 0; j <= nz; ++j)
      for (int i = 0; i <= nx; ++i) m << "v " << -400 + 800.0 * i / nx << " 0 " << 20 - 2020.0 * j / nz << "\n";
    for (int j = 0; j < nz; ++j)
      for (int i = 0; i < nx; ++i) {
        const int a = j * (nx + 1) + i + 1, b = a + 1, c = a + nx + 2, d = a + nx + 1;
        m << "f " << a << " " << b << " " << c << "\nf " << a << " " << c << " " << d << "\n";
      }
    return m.str();
  }());
  constexpr int kSpp = 16;
  constexpr double kNear = 0.5, kFar = 30;
  for (const char* depth : {"plane", "per-sample"}) {
    SCOPED_TRACE(std::string("depth = ") + depth);
    const std::string scene =
        box.write("s.toml", "width = 80\nheight = 60\nspp = 16\ndepth = \"" + std::string(depth) +
                                "\"\n[camera]\neye = [0, 1, 0]\ntarget = [0, 1, -1]\nfov_y = 60\nnear = 0.5\nfar = 30\n"
                                "[[object]]\nmesh = \"floor.obj\"\nopacity = 0.5\n");
    const SceneSpec s = load_scene_file(scene);
    ASSERT_EQ(s.spp, kSpp);
    CaptureStats st;
    const auto frags = capture_fragments(s, &st);
    EXPECT_GT(st.clipped, 0u) << "the floor must cross the near and far planes";
    const auto n = sample_counts(s, frags);
    // Ray through screen y hits the floor (1 below the eye) at view-axis
    // distance d = 1 / tan(angle below the axis).
    const double t = std::tan(30.0 * 3.14159265358979 / 180.0);
    const auto pos = standard_sample_positions(kSpp);
    const auto distance = [&](uint32_t y, int k) {                                 // +inf above the horizon
      const double ndc_y = 1.0 - 2.0 * (y + pos[size_t(k)].y / 256.0) / s.height;  // + up
      const double down = -ndc_y * t;                                              // tan of the angle below
      return down > 0 ? 1.0 / down : HUGE_VAL;
    };
    uint64_t visible = 0;
    for (uint32_t y = 0; y < s.height; ++y)
      for (uint32_t x = 0; x < s.width; ++x)
        for (int k = 0; k < kSpp; ++k) {
          const int c = n[(size_t(y) * s.width + x) * kSpp + size_t(k)];
          ASSERT_LE(c, 1) << "sample covered twice at (" << x << ", " << y << ")";
          const double dist = distance(y, k);
          if (dist < kFar * 0.9) {
            ASSERT_EQ(c, 1) << "floor missing at (" << x << ", " << y << "), distance " << dist;
            ++visible;
          }
          if (dist > kFar * 1.1) {
            ASSERT_EQ(c, 0) << "beyond the far plane or above the horizon at (" << x << ", " << y << ")";
          }
        }
    EXPECT_GT(visible, uint64_t(s.width) * s.height * kSpp / 3) << "the floor must fill the lower part of the screen";
    const TraceHeader h = capture_header(s);
    for (const auto& f : frags) {
      std::array<float, 64> z;
      z.fill(std::nanf(""));  // an entry the evaluation does not write fails every comparison below
      fragment_sample_depths(h, f, z.data());
      for (uint64_t m = f.coverage; m; m &= m - 1) {
        const int k = __builtin_ctzll(m);
        const double dist = distance(f.y, k);
        ASSERT_TRUE(std::isfinite(dist)) << "sample above the horizon covered at (" << f.x << ", " << f.y << ")";
        const double want = std::clamp(kFar / (kFar - kNear) * (1.0 - kNear / dist), 0.0, 1.0);
        ASSERT_TRUE(z[size_t(k)] >= 0.0f && z[size_t(k)] <= 1.0f)
            << "depth " << z[size_t(k)] << " of sample " << k << " at (" << f.x << ", " << f.y << ")";
        // The binary32 pipeline (clip coordinates, divide, plane) is off by
        // under 2e-7 here; another sample of the pixel is over 1e-3 away.
        ASSERT_NEAR(z[size_t(k)], want, 1e-6)
            << "sample " << k << " at (" << f.x << ", " << f.y << "), distance " << dist;
      }
    }
  }
}

TEST(CaptureClipping, TrianglesBehindTheCameraOrBeyondFarGiveNothing) {
  Scratch box;
  box.write("t.obj", "v -1 -1 10\nv 1 -1 10\nv 0 1 10\nv -1 -1 -100\nv 1 -1 -100\nv 0 1 -100\nf 1 2 3\nf 4 5 6\n");
  const std::string scene = box.write("s.toml", scene_text("[[object]]\nmesh = \"t.obj\"\nopacity = 0.5\n"));
  const SceneSpec s = load_scene_file(scene);
  CaptureStats st;
  EXPECT_TRUE(capture_fragments(s, &st).empty());
  EXPECT_EQ(st.outside, 2u);
}

// Every capture writes the D3D / Vulkan standard positions into its header.
TEST(CaptureSamplePositions, TraceHeadersHoldTheStandardPositionsExactly) {
  // D3D11 / Vulkan standard sample locations, 1/16 pixel offsets from the centre.
  const std::map<int, std::vector<std::pair<int, int>>> expect = {
      {2, {{4, 4}, {-4, -4}}},
      {4, {{-2, -6}, {6, -2}, {-6, 2}, {2, 6}}},
      {8, {{1, -3}, {-1, 3}, {5, 1}, {-3, -5}, {-5, 5}, {-7, -1}, {3, 7}, {7, -7}}},
      {16,
       {{1, 1},
        {-1, -3},
        {-3, 2},
        {4, -1},
        {-5, -2},
        {2, 5},
        {5, 3},
        {3, -5},
        {-2, 6},
        {0, -7},
        {-4, -6},
        {-6, 4},
        {-8, 0},
        {7, -4},
        {6, 7},
        {-7, -8}}}};
  Scratch box;
  box.write("t.obj", "v -1 -1 0\nv 1 -1 0\nv 0 1 0\nf 1 2 3\n");
  for (const auto& [spp, pos] : expect) {
    const std::string scene =
        box.write("s.toml", scene_text("[[object]]\nmesh = \"t.obj\"\n", "eye = [0, 0, 5]\ntarget = [0, 0, 0]",
                                       "width = 16\nheight = 16\nspp = " + std::to_string(spp) + "\n"));
    capture_to_file(load_scene_file(scene), box.path("t.trace"));
    TraceReader r(box.path("t.trace"));
    ASSERT_EQ(r.header().spp, spp);
    for (size_t i = 0; i < pos.size(); ++i) {
      EXPECT_EQ(r.header().positions[i].x, 128 + 16 * pos[i].first) << spp << " spp sample " << i;
      EXPECT_EQ(r.header().positions[i].y, 128 + 16 * pos[i].second) << spp << " spp sample " << i;
    }
  }
}

// glTF materials: alphaMode BLEND takes the base colour's alpha, MASK below
// the cutoff draws nothing but still uses its primitive id, OPAQUE is 1.
TEST(CaptureMaterials, GltfAlphaModes) {
  Scratch box;
  // Three triangles side by side (9 float3 positions, 108 bytes), one primitive each.
  std::vector<float> p = {-3, -1, 0, -1, -1, 0, -2, 1, 0, -1, -1, 0, 1, -1, 0, 0, 1, 0, 1, -1, 0, 3, -1, 0, 2, 1, 0};
  const std::string enc = base64(raw_bytes(p));
  std::string prims, acc;
  for (int i = 0; i < 3; ++i) {
    prims += std::string(i ? "," : "") + "{\"attributes\":{\"POSITION\":" + std::to_string(i) +
             "},\"material\":" + std::to_string(i) + "}";
    acc += std::string(i ? "," : "") + "{\"bufferView\":0,\"byteOffset\":" + std::to_string(36 * i) +
           ",\"componentType\":5126,\"count\":3,\"type\":\"VEC3\",\"min\":[-3,-1,0],\"max\":[3,1,0]}";
  }
  box.write("m.gltf", R"({"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],
"meshes":[{"primitives":[)" +
                          prims + R"(]}],
"materials":[{"pbrMetallicRoughness":{"baseColorFactor":[1,0,0,0.25]},"alphaMode":"BLEND"},
             {"pbrMetallicRoughness":{"baseColorFactor":[0,1,0,0.25]},"alphaMode":"MASK","alphaCutoff":0.5},
             {"pbrMetallicRoughness":{"baseColorFactor":[0,0,1,0.25]}}],
"accessors":[)" + acc + R"(],
"bufferViews":[{"buffer":0,"byteLength":108}],
"buffers":[{"byteLength":108,"uri":"data:application/octet-stream;base64,)" +
                          enc + R"("}]})");
  const std::string scene =
      box.write("s.toml", scene_text("[[object]]\nmesh = \"m.gltf\"\nopacity = \"material\"\ncolor = \"material\"\n"
                                     "shading = \"unlit\"\n"));
  const SceneSpec s = load_scene_file(scene);
  CaptureStats st;
  const auto frags = capture_fragments(s, &st);
  EXPECT_EQ(st.discarded, 1u) << "the MASK triangle (alpha 0.25 < cutoff 0.5) draws nothing";
  std::map<uint32_t, std::pair<std::array<float, 3>, float>> by_prim;
  for (const auto& f : frags) by_prim[f.prim_id] = {f.rgb, f.alpha};
  ASSERT_EQ(by_prim.size(), 2u);
  ASSERT_TRUE(by_prim.count(0) && by_prim.count(2)) << "primitive ids follow the submission (MASK keeps id 1)";
  EXPECT_NEAR(by_prim[0].second, 0.25f, 1e-6);
  EXPECT_NEAR(by_prim[0].first[0], 1.0f, 1e-6);
  EXPECT_NEAR(by_prim[2].second, 1.0f, 1e-6) << "OPAQUE ignores the base colour's alpha";
  EXPECT_NEAR(by_prim[2].first[2], 1.0f, 1e-6);
}

// Textures: an object texture multiplies colour and opacity, sampled at each
// fragment's perspective-correct texture coordinates; a glTF MASK material
// with a base colour texture discards fragments below the cutoff.
TEST(CaptureTextures, ObjectTextureAndGltfMaskTexture) {
  Scratch box;
  // 4 x 1 texels: red transparent, red transparent, green opaque, green opaque.
  box.write("t.tga", tga(4, 1, {{255, 0, 0, 0}, {255, 0, 0, 0}, {0, 255, 0, 255}, {0, 255, 0, 255}}));
  box.write("quad.obj",
            "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
            "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n");
  // The quad fills x in [16, 48) of a 64 x 64 screen (fov 90, distance 2).
  auto scene = [&](const std::string& obj) {
    return box.write("s.toml",
                     "width = 64\nheight = 64\nspp = 4\n[camera]\neye = [0, 0, 2]\ntarget = [0, 0, 0]\n"
                     "fov_y = 90\nnear = 1\nfar = 10\n" +
                         obj);
  };
  const SceneSpec s =
      load_scene_file(scene("[[object]]\nmesh = \"quad.obj\"\ntexture = \"t.tga\"\nopacity = 0.5\n"
                            "shading = \"unlit\"\n"));
  int left = 0, right = 0;
  for (const auto& f : capture_fragments(s)) {
    const double u = (f.x + 0.5 - 16) / 32;
    if (u > 0.15 && u < 0.35) {  // texels 0 and 1 only (bilinear, repeat)
      ++left;
      EXPECT_EQ(f.alpha, 0.0f) << "pixel " << f.x;
      EXPECT_NEAR(f.rgb[0], 1.0f, 1e-6);
    }
    if (u > 0.65 && u < 0.85) {  // texels 2 and 3 only
      ++right;
      EXPECT_NEAR(f.alpha, 0.5f, 1e-6) << "opacity 0.5 x texel alpha 1, pixel " << f.x;
      EXPECT_NEAR(f.rgb[1], 1.0f, 1e-6);
    }
  }
  EXPECT_GT(left, 100);
  EXPECT_GT(right, 100);
  // glTF: the same quad, alphaMode MASK, the texture as baseColorTexture.
  const std::vector<float> pos = {-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0}, uv = {0, 1, 1, 1, 1, 0, 0, 0};
  const std::vector<uint16_t> idx = {0, 1, 2, 0, 2, 3};
  const std::string buf = raw_bytes(pos) + raw_bytes(uv) + raw_bytes(idx);
  box.write("q.gltf", R"({"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],
"meshes":[{"primitives":[{"attributes":{"POSITION":0,"TEXCOORD_0":1},"indices":2,"material":0}]}],
"materials":[{"pbrMetallicRoughness":{"baseColorFactor":[1,1,1,1],"baseColorTexture":{"index":0}},
              "alphaMode":"MASK","alphaCutoff":0.5}],
"textures":[{"source":0}],"images":[{"uri":"t.tga"}],
"accessors":[{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[-1,-1,0],"max":[1,1,0]},
             {"bufferView":1,"componentType":5126,"count":4,"type":"VEC2"},
             {"bufferView":2,"componentType":5123,"count":6,"type":"SCALAR"}],
"bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":48},{"buffer":0,"byteOffset":48,"byteLength":32},
               {"buffer":0,"byteOffset":80,"byteLength":12}],
"buffers":[{"byteLength":92,"uri":"data:application/octet-stream;base64,)" +
                          base64(buf) + R"("}]})");
  const SceneSpec g =
      load_scene_file(scene("[[object]]\nmesh = \"q.gltf\"\nopacity = \"material\"\n"
                            "color = \"material\"\nshading = \"unlit\"\n"));
  CaptureStats st;
  const auto frags = capture_fragments(g, &st);
  EXPECT_GT(st.discarded_fragments, 100u) << "the transparent half is discarded";
  ASSERT_GT(frags.size(), 100u);
  for (const auto& f : frags) {
    EXPECT_EQ(f.alpha, 1.0f) << "MASK fragments that pass are opaque";
    EXPECT_GE(f.x, 31) << "only the opaque (right) half passes the cutoff";
  }
}

// Flat and smooth two-sided diffuse shading, constant colours, and the draw
// order: shuffled is a seeded permutation of the authored primitives.
TEST(CaptureOrder, ShuffledIsASeededPermutation) {
  Scratch box;
  box.write("grid.obj", grid_obj(8, 1.0, 7));
  auto prims = [&](const std::string& order, int seed) {
    const std::string scene =
        box.write("s.toml", scene_text("[[object]]\nmesh = \"grid.obj\"\nopacity = 0.4\norder = \"" + order + "\"\n",
                                       "eye = [0, 0, 5]\ntarget = [0, 0, 0]",
                                       "width = 64\nheight = 48\nspp = 4\nseed = " + std::to_string(seed) + "\n"));
    const PreparedScene ps = prepare_scene(load_scene_file(scene));
    std::vector<std::array<float, 4>> first;
    for (const auto& t : ps.draws[0].triangles) first.push_back(t.v[0].pos);
    return first;
  };
  const auto a = prims("authored", 1), s1 = prims("shuffled", 1), s1b = prims("shuffled", 1), s2 = prims("shuffled", 2);
  EXPECT_EQ(s1, s1b) << "same seed, same order";
  EXPECT_NE(s1, a) << "shuffled must differ from the authored order";
  EXPECT_NE(s1, s2) << "the seed must change the order";
  auto sorted = [](std::vector<std::array<float, 4>> v) {
    std::sort(v.begin(), v.end());
    return v;
  };
  EXPECT_EQ(sorted(s1), sorted(a)) << "a permutation: the same triangles";
}

// Depth orders: a draw's triangles sorted by the view depth (clip w) of their
// centroids, farthest or nearest first; the same triangles as authored.
TEST(CaptureOrder, DepthOrdersSortByViewDepthAndPermute) {
  Scratch box;
  box.write("grid.obj", grid_obj(8, 1.0, 7));
  auto tris = [&](const std::string& order) {
    const std::string scene =
        box.write("s.toml", scene_text("[[object]]\nmesh = \"grid.obj\"\nopacity = 0.4\norder = \"" + order + "\"\n",
                                       "eye = [1, 4, 5]\ntarget = [0, 0, 0]", "width = 64\nheight = 48\nspp = 4\n"));
    const PreparedScene ps = prepare_scene(load_scene_file(scene));
    std::vector<std::array<std::array<float, 4>, 3>> v;
    for (const auto& t : ps.draws[0].triangles) v.push_back({t.v[0].pos, t.v[1].pos, t.v[2].pos});
    return v;
  };
  auto depth = [](const std::array<std::array<float, 4>, 3>& t) {
    return double(t[0][3]) + double(t[1][3]) + double(t[2][3]);
  };
  const auto a = tris("authored"), far = tris("far-to-near"), near = tris("near-to-far");
  ASSERT_GT(a.size(), 50u);
  size_t distinct = 0;
  for (size_t i = 1; i < far.size(); ++i) {
    EXPECT_GE(depth(far[i - 1]), depth(far[i])) << "far-to-near: triangle " << i << " is farther than the one before";
    EXPECT_LE(depth(near[i - 1]), depth(near[i])) << "near-to-far: triangle " << i << " is nearer than the one before";
    distinct += depth(far[i - 1]) != depth(far[i]);
  }
  EXPECT_GT(distinct, far.size() / 4) << "the view must see the grid at varying depths, or the test proves nothing";
  EXPECT_NE(far, a);
  auto sorted = [](auto v) {
    std::sort(v.begin(), v.end());
    return v;
  };
  EXPECT_EQ(sorted(far), sorted(a)) << "a permutation: the same triangles";
  EXPECT_EQ(sorted(near), sorted(a)) << "a permutation: the same triangles";
}

// Bad input: a clear one-line error naming the file and key, exit 1, no output.
TEST(CaptureBadInput, ErrorsNameTheFileAndKeyAndLeaveNoOutput) {
  Scratch box;
  box.write("t.obj", "v -1 -1 0\nv 1 -1 0\nv 0 1 0\nf 1 2 3\n");
  const std::string obj = "[[object]]\nmesh = \"t.obj\"\nopacity = 0.5\n";
  expect_capture_error(box, box.path("none.toml"), {"none.toml", "no such scene file"});
  expect_capture_error(box, box.write("a.toml", scene_text("[[object]]\nmesh = \"missing.obj\"\n")),
                       {"a.toml", "missing.obj", "no such mesh file"});
  box.write("corrupt.glb", std::string("glTF\x02\0\0\0garbage that is not a glTF binary", 40));
  expect_capture_error(box, box.write("b.toml", scene_text("[[object]]\nmesh = \"corrupt.glb\"\n")),
                       {"b.toml", "corrupt.glb", "cannot load the mesh"});
  box.write("nan.obj", "v -1 -1 0\nv nan 1 0\nv 0 1 0\nf 1 2 3\n");
  expect_capture_error(box, box.write("c.toml", scene_text("[[object]]\nmesh = \"nan.obj\"\n")),
                       {"c.toml", "nan.obj", "vertex 1", "not finite"});
  expect_capture_error(box, box.write("d.toml", scene_text("")), {"d.toml", "object", "no objects"});
  expect_capture_error(box, box.write("e.toml", scene_text(obj + "colour = [1, 0, 0]\n")),
                       {"e.toml", "object[0].colour", "unknown key"});
  expect_capture_error(box, box.write("f.toml", scene_text(obj, "eye = [0, 0, 5]\ntarget = [0, 0, 0]\nzoom = 2")),
                       {"f.toml", "camera.zoom", "unknown key"});
  expect_capture_error(box, box.write("g.toml", scene_text("[[object]]\nmesh = \"t.obj\"\nopacity = 1.5\n")),
                       {"g.toml", "object[0].opacity", "[0, 1]"});
  expect_capture_error(box, box.write("h.toml", scene_text(obj, "eye = [0, 0, 5]\ntarget = [0, 0, 0]", "spp = 3\n")),
                       {"h.toml", "spp", "one of 1, 2, 4"});
  expect_capture_error(box, box.write("i.toml", scene_text(obj, "eye = [0, 0, 5]\ntarget = [0, 0, 5]")),
                       {"i.toml", "camera.target", "equals eye"});
  expect_capture_error(box, box.write("j.toml", scene_text(obj, "eye = [0, 0, 5]\ntarget = [0, 0, 0]\nup = \"y\"")),
                       {"j.toml", "camera.up", "3 numbers"});
  expect_capture_error(box, box.write("k.toml", "width = 64\nwidth = 32\n"), {"k.toml:2"});
  expect_capture_error(box, box.write("l.toml", scene_text(obj + "order = \"random\"\n")),
                       {"l.toml", "object[0].order", "\"authored\", \"shuffled\""});
  // A scene named after a file name that is not UTF-8 (a trace's scene name
  // must be): the error names the scene file, which can set a name instead.
  expect_capture_error(box, box.write("caf\xe9.toml", scene_text(obj)), {"caf", ".toml", "not valid UTF-8", "name ="});
  EXPECT_EQ(load_scene_file(box.write("caf\xe9-named.toml", "name = \"caf\xc3\xa9\"\n" + scene_text(obj))).name,
            "caf\xc3\xa9");
  // Nothing visible: the camera looks away from the triangle.
  expect_capture_error(box, box.write("m.toml", scene_text(obj, "eye = [0, 0, 5]\ntarget = [0, 0, 10]")),
                       {"m.toml", "nothing visible", "1 outside the view frustum"});
  // ... which --allow-empty turns into a valid trace with no fragment.
  const CliResult r =
      run_cli(box, "capture '" + box.path("m.toml") + "' --allow-empty --quiet -o '" + box.path("empty.trace") + "'");
  EXPECT_EQ(r.code, 0) << r.err;
  TraceReader tr(box.path("empty.trace"));
  Fragment f;
  EXPECT_FALSE(tr.next(f));
}

// The camera inside a closed mesh: the near plane clips it, the back faces
// (kept for a transparent object) surround the camera and cover every sample.
TEST(CaptureBadInput, CameraInsideGeometryIsClippedAndSeesTheInside) {
  Scratch box;
  box.write(
      "cube.obj",
      "v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1\n"
      "f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 4 7 3\nf 4 8 7\nf 1 5 8\nf 1 8 4\nf 2 3 7\nf 2 7 6\n");
  const std::string scene =
      box.write("s.toml",
                "width = 40\nheight = 30\nspp = 4\n[camera]\neye = [0.2, 0.1, 0.3]\ntarget = [1, 0.3, -1]\n"
                "fov_y = 100\nnear = 0.05\nfar = 10\n[[object]]\nmesh = \"cube.obj\"\nopacity = 0.5\n");
  const SceneSpec s = load_scene_file(scene);
  const CaptureStats st = capture_to_file(s, box.path("in.trace"));
  EXPECT_GT(st.fragments, 0u);
  TraceReader r(box.path("in.trace"));
  std::vector<Fragment> frags;
  for (Fragment f; r.next(f);) frags.push_back(f);
  const auto n = sample_counts(s, frags);
  for (size_t i = 0; i < n.size(); ++i)
    ASSERT_EQ(n[i], 1) << "inside a closed cube each sample sees one wall, sample " << i;
  // A camera with its near plane cutting a mesh is not an error either.
  const std::string cut =
      box.write("cut.toml",
                "width = 40\nheight = 30\nspp = 4\n[camera]\neye = [0, 0, 1.2]\ntarget = [0, 0, 0]\n"
                "fov_y = 60\nnear = 0.5\nfar = 10\n[[object]]\nmesh = \"cube.obj\"\nopacity = 0.5\n");
  CaptureStats cst;
  capture_fragments(load_scene_file(cut), &cst);
  EXPECT_GT(cst.clipped, 0u);
}

TEST(CaptureCli, WritesAValidTraceWithoutAProgressBarWhenNotATerminal) {
  Scratch box;
  box.write("grid.obj", grid_obj(6, 1.0, 3));
  const std::string scene =
      box.write("s.toml", scene_text("[[object]]\nmesh = \"grid.obj\"\nopacity = 0.4\ncolor = [0.2, 0.5, 1.0]\n"
                                     "shading = \"flat\"\norder = \"shuffled\"\n"));
  const CliResult r = run_cli(box, "capture '" + scene + "' -o '" + box.path("g.trace") + "' --spp 8 --width 50");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(r.err.empty()) << "no progress bar when stderr is not a terminal: " << r.err;
  EXPECT_NE(r.out.find("8 spp"), std::string::npos) << r.out;
  TraceReader tr(box.path("g.trace"));
  EXPECT_EQ(tr.header().spp, 8);
  EXPECT_EQ(tr.header().width, 50u);
  uint64_t n = 0;
  for (Fragment f; tr.next(f); ++n) {
    EXPECT_NEAR(f.alpha, 0.4f, 1e-6);
    EXPECT_GT(f.rgb[2], f.rgb[0]) << "the colour is blue-ish";
  }
  EXPECT_GT(n, 100u);
  // Deterministic: the same scene gives the same bytes.
  ASSERT_EQ(run_cli(box, "capture '" + scene + "' --quiet -o '" + box.path("h.trace") + "' --spp 8 --width 50").code,
            0);
  std::ifstream a(box.path("g.trace"), std::ios::binary), b(box.path("h.trace"), std::ios::binary);
  std::stringstream sa, sb;
  sa << a.rdbuf();
  sb << b.rdbuf();
  EXPECT_EQ(ropsim_test::first_byte_difference(sa.str(), sb.str()), "") << "two captures of one scene differ";
  EXPECT_TRUE(tr.header().checksummed) << "capture writes a checksummed payload by default";
  // --progress forces the progress into a log (stderr not a terminal).
  const CliResult pr =
      run_cli(box, "capture '" + scene + "' --progress -o '" + box.path("q.trace") + "' --spp 8 --width 50");
  ASSERT_EQ(pr.code, 0) << pr.err;
  EXPECT_NE(pr.err.find("capture: 100.0 %"), std::string::npos) << "--progress shows the capture's end: " << pr.err;
  // --no-checksum: the same fragments, in the layout without checksum records.
  ASSERT_EQ(
      run_cli(box, "capture '" + scene + "' --quiet --no-checksum -o '" + box.path("p.trace") + "' --spp 8 --width 50")
          .code,
      0);
  TraceReader tp(box.path("p.trace"));
  EXPECT_FALSE(tp.header().checksummed);
  TraceReader tg(box.path("g.trace"));
  uint64_t same = 0;
  for (Fragment f, g; tp.next(f);) {
    ASSERT_TRUE(tg.next(g)) << "the --no-checksum trace has more fragments";
    same += f.prim_id == g.prim_id && f.x == g.x && f.y == g.y && f.coverage == g.coverage;
  }
  EXPECT_EQ(same, n) << "the --no-checksum trace holds other fragments";
}

// The committed scene files parse, and load their meshes where present.
TEST(CaptureScenes, CommittedSceneFilesCapture) {
  for (const char* name : {"cloth.toml", "motor.toml", "smoke.toml", "fandisk.toml", "rocker-arm.toml"}) {
    SCOPED_TRACE(name);
    SceneOverrides o;
    o.width = 64;
    o.height = 48;
    o.spp = 4;
    const SceneSpec s = load_scene_file(repo_scene(name), o);
    if (std::string(name) != "cloth.toml" && !fs::exists(s.objects[0].mesh)) {
      std::cout << "[  SKIPPED ] " << name << ": shared mesh " << s.objects[0].mesh << " absent\n";
      continue;
    }
    CaptureStats st;
    const auto frags = capture_fragments(s, &st);
    EXPECT_GT(frags.size(), 500u) << "the object must fill a good part of the view";
    EXPECT_EQ(st.outside, 0u) << "the whole object must be in view";
  }
}

#ifdef ROPSIM_HAVE_OSMESA
// The same scene through Mesa's llvmpipe (GL 4.5 core, 4x MSAA) and through
// ropsim with Mesa's sample positions: >= 99.9 % of (draw, primitive, pixel)
// records agree exactly in their coverage masks, and the depths at the pixel
// centre agree within 1e-6 + 1e-3 px x |gradient| on >= 99.99 % of them
// (docs/capture.md "Cross-check" explains the remaining differences).
TEST(CaptureMesaCrossCheck, AgreesWithLlvmpipeOnMeshes) {
  std::vector<std::string> scenes = {repo_scene("cloth.toml")};
  const std::string dir = shared_mesh_dir();
  for (const char* m : {"fandisk.toml", "motor.toml"}) scenes.push_back(repo_scene(m));
  int ran = 0;
  for (const auto& path : scenes) {
    SCOPED_TRACE(path);
    SceneOverrides o;
    o.width = 320;
    o.height = 240;
    const SceneSpec s = load_scene_file(path, o);
    if (!fs::exists(s.objects[0].mesh)) {
      std::cout << "[  SKIPPED ] " << path << ": shared mesh " << s.objects[0].mesh << " absent\n";
      continue;
    }
    const CrossCheckResult r = cross_check_with_mesa(s);
    std::cout << cross_check_summary(r);
    ++ran;
    EXPECT_EQ(r.positions, "(96,32) (224,96) (32,160) (160,224)") << "llvmpipe's 4x pattern is the standard one";
    EXPECT_GT(r.ours, 10000u);
    EXPECT_GE(r.agreement, 0.999) << "records agreeing exactly: " << r.equal << " of "
                                  << r.equal + r.mask_differs + r.only_ours + r.only_mesa;
    EXPECT_EQ(r.farther, 0u) << "coverage differences must all be within 1/256 pixel of an edge (snapping)";
    EXPECT_LE(r.depth_over_tolerance, (r.equal + r.mask_differs) / 10000) << "max |dz| " << r.max_depth_diff;
    EXPECT_LT(r.max_depth_diff, 1e-3);
  }
  if (ran < 2) GTEST_SKIP() << "the shared meshes (" << dir << ") are absent: only " << ran << " mesh cross-checked";
}
#endif
