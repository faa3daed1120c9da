// Writing a trace file, versions 1 and 2 (docs/trace-format.md).
#include <sys/stat.h>
#include <sys/types.h>
#include <xxhash.h>
#include <zstd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstdlib>
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

namespace {

/// The header's bytes as the file starts with them (its check excluded, the
/// count's reserved bytes 0).
std::vector<uint8_t> encode_head(const TraceHeader& header) {
  uint8_t fixed[kFixedHeaderBytes] = {};
  std::memcpy(fixed, kTraceMagic, 8);
  put_u16(fixed + 8, header.version());
  put_u16(fixed + 10, header.checksummed ? kTraceFlagChecksum | kTraceFlagHeaderCheck : 0);
  put_u32(fixed + 12, header.width);
  put_u32(fixed + 16, header.height);
  fixed[20] = uint8_t(header.spp);
  fixed[21] = uint8_t(header.depth_mode);
  fixed[22] = uint8_t(header.color_format);
  fixed[23] = uint8_t(header.compression);
  for (int i = 0; i < 3; ++i) put_f32(fixed + 24 + 4 * i, header.clear_color[i]);
  put_f32(fixed + 36, header.clear_depth);
  put_u16(fixed + 40, uint16_t(header.scene_name.size()));
  std::vector<uint8_t> head(fixed, fixed + sizeof fixed);
  for (int i = 0; i < header.spp; ++i) {
    head.push_back(header.positions[i].x);
    head.push_back(header.positions[i].y);
  }
  head.insert(head.end(), header.scene_name.begin(), header.scene_name.end());
  if (!header.draws.empty()) encode_draw_table(head, header.draws);  // version 2 (section 1.5)
  return head;
}

/// The header check: XXH3-64 of the header's bytes, little-endian.
std::array<uint8_t, kHeaderCheckBytes> header_check(const std::vector<uint8_t>& head) {
  std::array<uint8_t, kHeaderCheckBytes> c;
  put_u64(c.data(), XXH3_64bits(head.data(), head.size()));
  return c;
}

/// Whether two headers frame and encode records alike.
bool same_layout(const TraceHeader& a, const TraceHeader& b) {
  return a.width == b.width && a.height == b.height && a.spp == b.spp && a.depth_mode == b.depth_mode &&
         a.color_format == b.color_format && a.compression == b.compression && a.checksummed == b.checksummed;
}

}  // namespace

/// A header-last writer's compressed records, gathered in chunks of memory
/// as they come: each byte is written once, none is copied when the payload
/// grows (a memory stream copies and clears its whole buffer each time it
/// doubles, which for a payload of many MB costs more than compressing it).
struct TraceWriter::Payload {
  static constexpr size_t kChunkBytes = size_t(8) << 20;
  std::vector<std::unique_ptr<uint8_t[]>> chunks;
  size_t used = 0;  ///< bytes in the last chunk
  void append(const char* b, size_t n) {
    while (n > 0) {
      if (chunks.empty() || used == kChunkBytes) {
        chunks.emplace_back(new uint8_t[kChunkBytes]);  // not zeroed: only what is written is touched
        used = 0;
      }
      const size_t k = std::min(n, kChunkBytes - used);
      std::memcpy(chunks.back().get() + used, b, k);
      used += k;
      b += k;
      n -= k;
    }
  }
  static ssize_t write(void* cookie, const char* b, size_t n) {
    try {
      static_cast<Payload*>(cookie)->append(b, n);
    } catch (const std::bad_alloc&) {
      errno = ENOMEM;
      return -1;
    }
    return ssize_t(n);
  }
};

TraceWriter::TraceWriter(const std::string& path, const TraceHeader& header, int zstd_level, int zstd_workers)
    : path_(path), header_(header) {
  std::string err = validate_header(header_);
  if (!err.empty()) throw TraceError(path + ": header: " + err);
  out_ = std::make_unique<OutputFile>(path);
  FILE* f = out_->stream();
  head_ = encode_head(header_);
  // A failure here destroys out_, which removes the temporary file.
  const std::unique_ptr<ByteSink> raw = open_record_sink(f, path, Compression::kNone);
  raw->write(head_.data(), head_.size());
  if (header_.checksummed) raw->write(header_check(head_).data(), kHeaderCheckBytes);
  sink_ = open_record_sink(f, path, header_.compression, zstd_level, zstd_workers);
  if (header_.checksummed) block_.reserve(kChecksumBlockBytes);
}

TraceWriter::TraceWriter(const std::string& path, const TraceHeader& layout, int zstd_level, int zstd_workers,
                         HeaderLast)
    : path_(path), header_(layout) {
  std::string err = validate_header(header_);
  if (!err.empty()) throw TraceError(path + ": header: " + err);
  payload_bytes_ = std::make_unique<Payload>();
  cookie_io_functions_t io{};
  io.write = &Payload::write;
  payload_ = fopencookie(payload_bytes_.get(), "w", io);
  if (!payload_) throw TraceError(path + ": no memory for the records");
  sink_ = open_record_sink(payload_, path, header_.compression, zstd_level, zstd_workers);
  if (header_.checksummed) block_.reserve(kChecksumBlockBytes);
}

TraceWriter::~TraceWriter() {
  sink_.reset();
  out_.reset();  // discards the temporary file unless finish() committed it
  if (payload_) std::fclose(payload_);
}

size_t encode_fragment_record(const TraceHeader& h, const Fragment& f, uint8_t* b, std::string& error) {
  error = validate_fragment(h, f);
  if (!error.empty()) return 0;
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
  put_le(b + n, f.coverage, coverage_bytes(h.spp));
  n += size_t(coverage_bytes(h.spp));
  if (h.depth_mode == DepthMode::kPlane) {
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
  if (h.color_format == ColorFormat::kRgbF32) {
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
  return n;
}

void TraceWriter::write(const Fragment& f) {
  if (finished_ || !sink_) throw TraceError(path_ + ": write after finish()");
  uint8_t b[kMaxFragmentRecordBytes];
  std::string err;
  const size_t n = encode_fragment_record(header_, f, b, err);
  if (!n) throw TraceError(path_ + ": record " + std::to_string(count_) + ": " + err);
  append_records(b, n);
  ++count_;
}

void TraceWriter::write_records(const uint8_t* records, size_t bytes, uint64_t count) {
  if (finished_ || !sink_) throw TraceError(path_ + ": write after finish()");
  // Each record's length from its coverage (the tag and 12 bytes before it).
  const int cb = coverage_bytes(header_.spp);
  auto record_bytes = [&](const uint8_t* r) {
    uint64_t c = 0;
    for (int i = 0; i < cb; ++i) c |= uint64_t(r[13 + i]) << (8 * i);
    return fragment_record_bytes(header_, __builtin_popcountll(c));
  };
  // Runs of whole records, each as large as the block being gathered
  // still takes (a record never spans blocks).
  size_t at = 0;
  uint64_t seen = 0;
  while (at < bytes) {
    const size_t room = header_.checksummed ? kChecksumBlockBytes - block_.size() : bytes - at;
    size_t run = 0;
    while (at + run < bytes) {
      const uint8_t* r = records + at + run;
      const bool head = at + run + size_t(13 + cb) <= bytes;
      const size_t n = head ? record_bytes(r) : 0;
      if (!head || r[0] != kTagFragment || at + run + n > bytes)
        throw TraceError(path_ + ": record " + std::to_string(count_ + seen) + ": not a whole fragment record");
      if (run + n > room && (run > 0 || !block_.empty())) break;
      run += n;
      ++seen;
    }
    if (run == 0) {
      flush_block();  // the next record opens a block of its own
      continue;
    }
    append_records(records + at, run);
    at += run;
  }
  if (seen != count)
    throw TraceError(path_ + ": " + std::to_string(seen) + " fragment records given as " + std::to_string(count));
  count_ += count;
}

void TraceWriter::append_records(const uint8_t* b, size_t n) {
  if (header_.checksummed) {
    // A record never spans blocks: close the block before it would exceed kChecksumBlockBytes.
    if (block_.size() + n > kChecksumBlockBytes) flush_block();
    block_.insert(block_.end(), b, b + n);
  } else {
    sink_->write(b, n);
  }
  raw_bytes_ += n;
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

void TraceWriter::end_records() {
  flush_block();
  uint8_t b[9];
  b[0] = kTagEnd;
  put_u64(b + 1, count_);
  sink_->write(b, 9);
  raw_bytes_ += 9;
  sink_->close();
  sink_.reset();
}

void TraceWriter::finish(const TraceHeader& header) {
  if (finished_) return;
  if (!payload_) throw TraceError(path_ + ": finish(header) of a writer whose header is written");
  if (!same_layout(header, header_))
    throw TraceError(path_ + ": the header's layout is not the one the records were written for");
  std::string err = validate_header(header);
  if (!err.empty()) throw TraceError(path_ + ": header: " + err);
  header_ = header;
  end_records();
  if (std::fflush(payload_) != 0) throw TraceError(path_ + ": no memory for the records");
  // The header with the fragment count (as finish() patches it in), its check, the payload.
  head_ = encode_head(header_);
  if (count_ + 1 < (uint64_t{1} << 48)) put_u48(head_.data() + kHeaderCountOffset, count_ + 1);
  out_ = std::make_unique<OutputFile>(path_);
  const std::unique_ptr<ByteSink> raw = open_record_sink(out_->stream(), path_, Compression::kNone);
  raw->write(head_.data(), head_.size());
  if (header_.checksummed) raw->write(header_check(head_).data(), kHeaderCheckBytes);
  for (size_t c = 0; c < payload_bytes_->chunks.size(); ++c)
    raw->write(payload_bytes_->chunks[c].get(),
               c + 1 < payload_bytes_->chunks.size() ? Payload::kChunkBytes : payload_bytes_->used);
  raw->close();
  out_->commit();
  finished_ = true;
}

void TraceWriter::finish() {
  if (finished_) return;
  if (payload_) throw TraceError(path_ + ": a header-last writer ends with finish(header)");
  end_records();
  // The fragment count in the header's reserved bytes (count + 1; 0 =
  // not recorded), so a reader knows it without reading the payload. An
  // output that cannot seek (a FIFO, a device, stdout) keeps 0.
  // The header check covers the count: it is patched with it.
  if (count_ + 1 < (uint64_t{1} << 48)) {
    put_u48(head_.data() + kHeaderCountOffset, count_ + 1);
    if (out_->patch(kHeaderCountOffset, head_.data() + kHeaderCountOffset, 6) && header_.checksummed)
      out_->patch(head_.size(), header_check(head_).data(), kHeaderCheckBytes);
  }
  out_->commit();  // flush, fsync, close, rename: UserError on any failure
  finished_ = true;
}

}  // namespace ropsim
