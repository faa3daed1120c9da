#include "rtl_models/functional/fragment_source.h"

#include <filesystem>
#include <system_error>
#include <vector>

#include "traces/raster/rasterizer.h"

namespace ropsim {

std::string InputSpec::describe() const {
  const std::string times = repeat > 1 ? ", drawn " + std::to_string(repeat) + " times" : "";
  if (from_trace()) return trace_path + times;
  return "scene " + scene.name + " at " + std::to_string(scene.spp) + " spp" + times;
}

namespace {

class TraceFragments : public FragmentSource {
 public:
  TraceFragments(const std::string& path, uint32_t repeat, bool decode_ahead)
      : path_(path),
        repeat_(repeat),
        decode_ahead_(decode_ahead),
        reader_(std::make_unique<TraceReader>(path, decode_ahead)) {
    header_ = reader_->header();
  }
  bool next(Fragment& f) override {
    while (!reader_->next(f)) {
      if (pass_ >= repeat_) return false;
      ++pass_;
      reader_ = std::make_unique<TraceReader>(path_, decode_ahead_);
    }
    ++delivered_;
    return true;
  }
  uint64_t fragments_at_least() const override {
    if (header_.compression != Compression::kNone) return 0;
    std::error_code ec;
    const uint64_t bytes = std::filesystem::file_size(path_, ec);
    if (ec) return 0;
    // Every record is at most the largest one (all samples covered); the
    // header and checksum records (16 bytes per 64 KiB block) are a few bytes
    // more than the fragments, so take 1/1000 off.
    return bytes / fragment_record_bytes(header_, header_.spp) / 1000 * 999 * repeat_;
  }
  std::optional<uint64_t> fragments_known() const override {
    const std::optional<uint64_t> n = reader_->recorded_fragments();
    if (!n) return std::nullopt;
    return *n * repeat_;
  }
  double consumed() const override { return (double(pass_ - 1) + reader_->file_fraction()) / double(repeat_); }

 private:
  std::string path_;
  uint32_t repeat_, pass_ = 1;
  bool decode_ahead_;
  std::unique_ptr<TraceReader> reader_;
};

/// Rasterizes one triangle at a time into a small buffer.
class SceneFragments : public FragmentSource {
 public:
  SceneFragments(const SceneParams& p, uint32_t repeat) : scene_(build_scene(p)), repeat_(repeat) {
    header_ = scene_.header;
    raster_ = std::make_unique<Rasterizer>(scene_.header);
  }
  bool next(Fragment& f) override {
    while (at_ == buf_.size()) {
      buf_.clear();
      at_ = 0;
      if (tri_ == scene_.triangles.size()) {
        if (pass_ >= repeat_) return false;
        ++pass_;
        tri_ = 0;
      }
      raster_->rasterize(scene_.triangles[tri_++], [this](const Fragment& x) { buf_.push_back(x); });
    }
    f = buf_[at_++];
    ++delivered_;
    return true;
  }
  double consumed() const override {
    const double n = double(scene_.triangles.size());
    return (double(pass_ - 1) + (n > 0 ? double(tri_) / n : 1.0)) / double(repeat_);
  }

 private:
  Scene scene_;
  std::unique_ptr<Rasterizer> raster_;  // refers to scene_.header
  uint32_t repeat_, pass_ = 1;
  size_t tri_ = 0, at_ = 0;
  std::vector<Fragment> buf_;
};

class VectorFragments : public FragmentSource {
 public:
  VectorFragments(const TraceHeader& h, const std::vector<Fragment>& v) : v_(v) { header_ = h; }
  bool next(Fragment& f) override {
    if (at_ == v_.size()) return false;
    f = v_[at_++];
    ++delivered_;
    return true;
  }
  uint64_t fragments_at_least() const override { return v_.size(); }
  std::optional<uint64_t> fragments_known() const override { return v_.size(); }
  double consumed() const override { return v_.empty() ? 1.0 : double(at_) / double(v_.size()); }

 private:
  const std::vector<Fragment>& v_;
  size_t at_ = 0;
};

}  // namespace

std::unique_ptr<FragmentSource> fragments_from(const TraceHeader& h, const std::vector<Fragment>& fragments) {
  return std::make_unique<VectorFragments>(h, fragments);
}

std::unique_ptr<FragmentSource> open_fragments(const InputSpec& in) {
  if (in.from_trace()) return std::make_unique<TraceFragments>(in.trace_path, in.repeat, in.decode_ahead);
  return std::make_unique<SceneFragments>(in.scene, in.repeat);
}

}  // namespace ropsim
