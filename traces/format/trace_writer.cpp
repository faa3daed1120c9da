// Writing a trace file, versions 1 and 2 (docs/trace-format.md).
#include <sys/stat.h>
#include <xxhash.h>
#include <zstd.h>

#include <cerrno>
#include <cinttypes>
#include <cmath>
#include <cstring>
#include <vector>

#include "rtl_models/algo/bits.h"
#include "rtl_models/algo/depth.h"
#include "rtl_models/algo/numerics.h"
#include "traces/format/trace.h"
#include "traces/format/trace_stream.h"
#include "traces/format/utf8.h"
#include "util/byte_codec.h"
#include "util/errors.h"
#include "util/output_file.h"

namespace ropsim {

TraceWriter::TraceWriter(const std::string& path, const TraceHeader& header, int zstd_level, int zstd_workers)
    : path_(path), header_(header) {
  std::string err = validate_header(header_);
  if (!err.empty()) throw TraceError(path + ": header: " + err);
  out_ = std::make_unique<OutputFile>(path);
  FILE* f = out_->stream();
  uint8_t fixed[kFixedHeaderBytes] = {};
  std::memcpy(fixed, kTraceMagic, 8);
  put_u16(fixed + 8, header_.version());
  put_u16(fixed + 10, header_.checksummed ? kTraceFlagChecksum | kTraceFlagHeaderCheck : 0);
  put_u32(fixed + 12, header_.width);
  put_u32(fixed + 16, header_.height);
  fixed[20] = uint8_t(header_.spp);
  fixed[21] = uint8_t(header_.depth_mode);
  fixed[22] = uint8_t(header_.color_format);
  fixed[23] = uint8_t(header_.compression);
  for (int i = 0; i < 3; ++i) put_f32(fixed + 24 + 4 * i, header_.clear_color[i]);
  put_f32(fixed + 36, header_.clear_depth);
  put_u16(fixed + 40, uint16_t(header_.scene_name.size()));
  head_.assign(fixed, fixed + sizeof fixed);
  for (int i = 0; i < header_.spp; ++i) {
    head_.push_back(header_.positions[i].x);
    head_.push_back(header_.positions[i].y);
  }
  head_.insert(head_.end(), header_.scene_name.begin(), header_.scene_name.end());
  if (!header_.draws.empty()) encode_draw_table(head_, header_.draws);  // version 2 (section 1.5)
  // A failure here destroys out_, which removes the temporary file.
  const std::unique_ptr<ByteSink> raw = open_record_sink(f, path, Compression::kNone);
  raw->write(head_.data(), head_.size());
  if (header_.checksummed) {
    uint8_t c[kHeaderCheckBytes];
    put_u64(c, XXH3_64bits(head_.data(), head_.size()));
    raw->write(c, sizeof c);
  }
  sink_ = open_record_sink(f, path, header_.compression, zstd_level, zstd_workers);
  if (header_.checksummed) block_.reserve(kChecksumBlockBytes);
}

TraceWriter::~TraceWriter() {
  sink_.reset();
  out_.reset();  // discards the temporary file unless finish() committed it
}

void TraceWriter::write(const Fragment& f) {
  if (finished_ || !sink_) throw TraceError(path_ + ": write after finish()");
  std::string err = validate_fragment(header_, f);
  if (!err.empty()) throw TraceError(path_ + ": record " + std::to_string(count_) + ": " + err);
  uint8_t b[16 + 8 + 256 + 16];
  size_t n = 0;
  b[n++] = kTagFragment;
  put_u32(b + n, f.draw_id);
  n += 4;
  put_u32(b + n, f.prim_id);
  n += 4;
  put_u16(b + n, f.x);
  n += 2;
  put_u16(b + n, f.y);
  n += 2;
  put_le(b + n, f.coverage, coverage_bytes(header_.spp));
  n += size_t(coverage_bytes(header_.spp));
  if (header_.depth_mode == DepthMode::kPlane) {
    put_f32(b + n, f.z0);
    put_f32(b + n + 4, f.dzdx);
    put_f32(b + n + 8, f.dzdy);
    n += 12;
  } else {
    for (uint64_t m = f.coverage; m; m &= m - 1) {
      put_f32(b + n, f.z[__builtin_ctzll(m)]);
      n += 4;
    }
  }
  if (header_.color_format == ColorFormat::kRgbF32) {
    for (int i = 0; i < 3; ++i) {
      put_f32(b + n, f.rgb[i]);
      n += 4;
    }
  } else {
    for (int i = 0; i < 3; ++i) {
      float c = std::min(1.0f, std::max(0.0f, f.rgb[i]));
      b[n++] = uint8_t(std::lround(c * 255.0f));
    }
  }
  put_f32(b + n, f.alpha);
  n += 4;
  if (header_.checksummed) {
    // A record never spans blocks: close the block before it would exceed kChecksumBlockBytes.
    if (block_.size() + n > kChecksumBlockBytes) flush_block();
    block_.insert(block_.end(), b, b + n);
  } else {
    sink_->write(b, n);
  }
  raw_bytes_ += n;
  ++count_;
}

void TraceWriter::flush_block() {
  if (block_.empty()) return;
  uint8_t c[kChecksumRecordBytes];
  c[0] = kTagChecksum;
  put_u32(c + 1, uint32_t(block_.size()));
  put_u64(c + 5, XXH3_64bits(block_.data(), block_.size()));
  sink_->write(c, sizeof c);
  sink_->write(block_.data(), block_.size());
  block_.clear();
  ++blocks_;
}

void TraceWriter::finish() {
  if (finished_) return;
  flush_block();
  uint8_t b[9];
  b[0] = kTagEnd;
  put_u64(b + 1, count_);
  sink_->write(b, 9);
  raw_bytes_ += 9;
  sink_->close();
  sink_.reset();
  // The fragment count in the header's reserved bytes (count + 1; 0 =
  // not recorded), so a reader knows it without reading the payload. An
  // output that cannot seek (a FIFO, a device, stdout) keeps 0.
  // The header check covers the count: it is patched with it.
  if (count_ + 1 < (uint64_t{1} << 48)) {
    put_u48(head_.data() + kHeaderCountOffset, count_ + 1);
    if (out_->patch(kHeaderCountOffset, head_.data() + kHeaderCountOffset, 6) && header_.checksummed) {
      uint8_t c[kHeaderCheckBytes];
      put_u64(c, XXH3_64bits(head_.data(), head_.size()));
      out_->patch(head_.size(), c, sizeof c);
    }
  }
  out_->commit();  // flush, fsync, close, rename: UserError on any failure
  finished_ = true;
}

}  // namespace ropsim
