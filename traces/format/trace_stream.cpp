// The trace file's byte streams and draw-table records (trace_stream.h).
#include "traces/format/trace_stream.h"

#include <sys/stat.h>
#include <xxhash.h>
#include <zstd.h>

#include <array>
#include <cerrno>
#include <cinttypes>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

#include "rtl_models/algo/bits.h"
#include "rtl_models/algo/depth.h"
#include "rtl_models/algo/numerics.h"
#include "traces/format/trace.h"
#include "traces/format/utf8.h"
#include "util/byte_codec.h"
#include "util/errors.h"
#include "util/output_file.h"

namespace ropsim {

const char* to_string(DepthMode m) { return m == DepthMode::kPlane ? "plane" : "per-sample"; }
const char* to_string(ColorFormat f) { return f == ColorFormat::kRgbF32 ? "rgb-f32" : "rgb-unorm8"; }
const char* to_string(Compression c) { return c == Compression::kZstd ? "zstd" : "none"; }

void encode_draw_table(std::vector<uint8_t>& o, const DrawTable& t) {
  uint8_t c[4];
  put_u32(c, uint32_t(t.size()));
  o.insert(o.end(), c, c + 4);
  for (const DrawState& s : t.states()) {
    uint8_t r[kDrawRecordFixedBytes];
    put_u32(r, s.draw_id);
    r[4] = uint8_t((s.blend ? kDrawFlagBlend : 0) | (s.depth_test ? kDrawFlagDepthTest : 0) |
                   (s.depth_write ? kDrawFlagDepthWrite : 0));
    r[5] = uint8_t(s.eq_rgb);
    r[6] = uint8_t(s.eq_alpha);
    r[7] = uint8_t(s.src_rgb);
    r[8] = uint8_t(s.dst_rgb);
    r[9] = uint8_t(s.src_alpha);
    r[10] = uint8_t(s.dst_alpha);
    r[11] = uint8_t(s.depth_func);
    r[12] = s.color_mask;
    r[13] = uint8_t(s.encoding);
    for (int i = 0; i < 4; ++i) put_f32(r + 14 + 4 * i, s.blend_color[size_t(i)]);
    r[30] = uint8_t(s.name.size());  // validate(): at most 255 bytes
    o.insert(o.end(), r, r + sizeof r);
    o.insert(o.end(), s.name.begin(), s.name.end());
  }
}

/// Decodes one draw-state record's fixed part (the name follows it).
DrawState decode_draw_record(const uint8_t* r) {
  DrawState s;
  s.draw_id = get_u32(r);
  s.blend = (r[4] & kDrawFlagBlend) != 0;
  s.depth_test = (r[4] & kDrawFlagDepthTest) != 0;
  s.depth_write = (r[4] & kDrawFlagDepthWrite) != 0;
  s.eq_rgb = BlendEquation(r[5]);
  s.eq_alpha = BlendEquation(r[6]);
  s.src_rgb = BlendFactor(r[7]);
  s.dst_rgb = BlendFactor(r[8]);
  s.src_alpha = BlendFactor(r[9]);
  s.dst_alpha = BlendFactor(r[10]);
  s.depth_func = DepthFunc(r[11]);
  s.color_mask = r[12];
  s.encoding = TargetEncoding(r[13]);
  for (int i = 0; i < 4; ++i) s.blend_color[size_t(i)] = get_f32(r + 14 + 4 * i);
  return s;
}

namespace {

class FileSource : public ByteSource {
 public:
  explicit FileSource(FILE* f) : f_(f) {}
  size_t read(void* dst, size_t n) override {
    size_t got = std::fread(dst, 1, n, f_);
    consumed += got;
    return got;
  }

 private:
  FILE* f_;
};

/// The zstd frame's decoder: fread and ZSTD_decompressStream, kIoChunk at
/// a time. decode() fills out with the next bytes and returns their count,
/// 0 at the end of the data; a broken frame throws SourceError.
class ZstdDecoder {
 public:
  explicit ZstdDecoder(FILE* f) : f_(f), in_(kIoChunk) {
    ds_ = ZSTD_createDStream();
    ZSTD_initDStream(ds_);
  }
  ~ZstdDecoder() { ZSTD_freeDStream(ds_); }
  ZstdDecoder(const ZstdDecoder&) = delete;
  ZstdDecoder& operator=(const ZstdDecoder&) = delete;
  size_t decode(uint8_t* out, size_t cap) {
    for (;;) {
      if (in_pos_ == in_len_ && !eof_) {
        in_len_ = std::fread(in_.data(), 1, in_.size(), f_);
        in_pos_ = 0;
        if (in_len_ == 0) eof_ = true;
      }
      if (frame_done_) {
        // The payload is exactly one zstd frame: bytes after it are not trace data.
        if (in_pos_ < in_len_) throw SourceError("data after the end of the compressed frame");
        return 0;
      }
      // At the end of the file the decoder may still hold decoded data: call it
      // with empty input until it has nothing more to give.
      ZSTD_inBuffer ib{in_.data(), in_len_, in_pos_};
      ZSTD_outBuffer ob{out, cap, 0};
      size_t r = ZSTD_decompressStream(ds_, &ob, &ib);
      in_pos_ = ib.pos;
      if (ZSTD_isError(r)) throw SourceError(std::string("corrupt compressed data: ") + ZSTD_getErrorName(r));
      frame_done_ = r == 0;  // 0: the frame is complete (checksum verified) and fully flushed
      if (ob.pos > 0) return ob.pos;
      if (eof_ && in_pos_ == in_len_) return 0;  // truncated frame: frame_done() stays false
    }
  }
  bool frame_done() const { return frame_done_; }

 private:
  FILE* f_;
  ZSTD_DStream* ds_;
  std::vector<uint8_t> in_;
  size_t in_pos_ = 0, in_len_ = 0;
  bool eof_ = false;
  bool frame_done_ = false;
};

/// A source read out of decoded chunks: read() copies from the current chunk
/// and asks next_chunk() for another when it is used up.
class ChunkedSource : public ByteSource {
 public:
  size_t read(void* dst, size_t n) override {
    uint8_t* d = static_cast<uint8_t*>(dst);
    size_t done = 0;
    while (done < n) {
      if (at_ == len_) {
        at_ = 0;
        len_ = 0;
        if (!next_chunk(chunk_, len_)) break;
        continue;
      }
      const size_t k = std::min(n - done, len_ - at_);
      std::memcpy(d + done, chunk_ + at_, k);
      at_ += k;
      done += k;
    }
    consumed += done;
    return done;
  }

 protected:
  /// The next chunk of data (len > 0), or false at its end; the previous
  /// chunk is no longer read.
  virtual bool next_chunk(const uint8_t*& chunk, size_t& len) = 0;

 private:
  const uint8_t* chunk_ = nullptr;
  size_t at_ = 0, len_ = 0;
};

/// A zstd payload decoded as it is read, on the reader's thread.
class InlineZstdSource : public ChunkedSource {
 public:
  explicit InlineZstdSource(FILE* f) : dec_(f), out_(kIoChunk) {}
  bool complete() const override { return dec_.frame_done(); }

 private:
  bool next_chunk(const uint8_t*& chunk, size_t& len) override {
    len = dec_.decode(out_.data(), out_.size());
    chunk = out_.data();
    return len > 0;
  }
  ZstdDecoder dec_;
  std::vector<uint8_t> out_;
};

/// A zstd payload decoded on a thread of its own, kRing chunks ahead of the
/// reader: the trace's decompression runs beside the model that reads it
/// (a one-core model such as the cycle model gains the decoder's time). The
/// bytes, their order and every error are those of decoding in the reader's
/// thread: an error reaches the reader after every byte decoded before it.
/// The decoder thread touches only its FILE and its chunks; it ends with the
/// source (the destructor stops and joins it).
class ZstdSource : public ChunkedSource {
 public:
  explicit ZstdSource(FILE* f) : dec_(f) {
    for (Chunk& c : ring_) c.bytes.resize(kIoChunk);
    thread_ = std::thread([this] { decode_ahead(); });
  }
  ~ZstdSource() override {
    {
      std::lock_guard<std::mutex> l(m_);
      stop_ = true;
    }
    cv_.notify_all();
    thread_.join();
  }
  bool complete() const override {
    std::lock_guard<std::mutex> l(m_);
    return ended_ && frame_done_;
  }

 private:
  static constexpr size_t kRing = 4;
  struct Chunk {
    std::vector<uint8_t> bytes;
    size_t len = 0;
  };
  /// The reader is done with its chunk: the next one decoded, or false at the
  /// end of the data (an error is thrown here, where decoding in the
  /// reader's thread would have met it).
  bool next_chunk(const uint8_t*& chunk, size_t& len) override {
    std::unique_lock<std::mutex> l(m_);
    if (holding_) {  // hand the finished chunk back
      holding_ = false;
      head_ = (head_ + 1) % kRing;
      --ready_;
      cv_.notify_all();
    }
    cv_.wait(l, [this] { return ready_ > 0 || ended_; });
    if (ready_ == 0) {
      if (error_) std::rethrow_exception(error_);
      return false;
    }
    holding_ = true;
    chunk = ring_[head_].bytes.data();
    len = ring_[head_].len;
    return true;
  }
  void decode_ahead() {
    size_t tail = 0;
    for (;;) {
      {
        std::unique_lock<std::mutex> l(m_);
        cv_.wait(l, [this] { return ready_ < kRing || stop_; });
        if (stop_) return;
      }
      // The chunk at tail is the decoder's until it is counted ready.
      Chunk& c = ring_[tail];
      std::exception_ptr error;
      size_t got = 0;
      try {
        got = dec_.decode(c.bytes.data(), c.bytes.size());
      } catch (...) {
        error = std::current_exception();
      }
      std::lock_guard<std::mutex> l(m_);
      if (got > 0) {
        c.len = got;
        ++ready_;
        tail = (tail + 1) % kRing;
      } else {
        error_ = error;
        frame_done_ = dec_.frame_done();
        ended_ = true;
      }
      cv_.notify_all();
      if (ended_) return;
    }
  }
  ZstdDecoder dec_;
  std::array<Chunk, kRing> ring_;
  // The reader's side: its chunk is ring_[head_] while holding_.
  size_t head_ = 0;
  bool holding_ = false;
  // Shared, under m_: chunks decoded and not yet handed back, the end.
  mutable std::mutex m_;
  std::condition_variable cv_;
  size_t ready_ = 0;
  bool ended_ = false, frame_done_ = false, stop_ = false;
  std::exception_ptr error_;
  std::thread thread_;
};

class FileSink : public ByteSink {
 public:
  FileSink(FILE* f, std::string path) : f_(f), path_(std::move(path)) {}
  void write(const void* src, size_t n) override {
    if (n && std::fwrite(src, 1, n, f_) != n) throw UserError(path_ + ": " + std::strerror(errno ? errno : EIO));
  }
  void close() override {}

 protected:
  FILE* f_;
  std::string path_;
};

class ZstdSink : public FileSink {
 public:
  ZstdSink(FILE* f, std::string path, int level, int workers)
      : FileSink(f, std::move(path)), buf_(ZSTD_CStreamOutSize()) {
    cs_ = ZSTD_createCCtx();
    ZSTD_CCtx_setParameter(cs_, ZSTD_c_compressionLevel, level);
    ZSTD_CCtx_setParameter(cs_, ZSTD_c_checksumFlag, 1);
    // A libzstd built without threads refuses workers: then the one thread.
    if (workers > 0 && ZSTD_isError(ZSTD_CCtx_setParameter(cs_, ZSTD_c_nbWorkers, workers)))
      ZSTD_CCtx_setParameter(cs_, ZSTD_c_nbWorkers, 0);
    pending_.reserve(kIoChunk);
  }
  ~ZstdSink() override { ZSTD_freeCCtx(cs_); }
  void write(const void* src, size_t n) override {
    const uint8_t* s = static_cast<const uint8_t*>(src);
    pending_.insert(pending_.end(), s, s + n);
    if (pending_.size() >= kIoChunk) flush(ZSTD_e_continue);
  }
  void close() override { flush(ZSTD_e_end); }

 private:
  void flush(ZSTD_EndDirective mode) {
    ZSTD_inBuffer ib{pending_.data(), pending_.size(), 0};
    for (;;) {
      ZSTD_outBuffer ob{buf_.data(), buf_.size(), 0};
      size_t r = ZSTD_compressStream2(cs_, &ob, &ib, mode);
      if (ZSTD_isError(r)) throw TraceError(path_ + ": compression failed: " + ZSTD_getErrorName(r));
      FileSink::write(buf_.data(), ob.pos);
      if (mode == ZSTD_e_end ? r == 0 : ib.pos == ib.size) break;
    }
    pending_.clear();
  }
  ZSTD_CCtx* cs_;
  std::vector<uint8_t> buf_, pending_;
};

}  // namespace

std::unique_ptr<ByteSource> open_record_source(FILE* f, Compression c, bool decode_ahead) {
  if (c == Compression::kZstd && decode_ahead) return std::make_unique<ZstdSource>(f);
  if (c == Compression::kZstd) return std::make_unique<InlineZstdSource>(f);
  return std::make_unique<FileSource>(f);
}

std::unique_ptr<ByteSink> open_record_sink(FILE* f, const std::string& path, Compression c, int zstd_level,
                                           int zstd_workers) {
  if (c == Compression::kZstd) return std::make_unique<ZstdSink>(f, path, zstd_level, zstd_workers);
  return std::make_unique<FileSink>(f, path);
}

std::string validate_header(const TraceHeader& h) {
  if (h.width == 0 || h.height == 0) return "width and height must be at least 1";
  if (h.width > kMaxScreenSide || h.height > kMaxScreenSide)
    return "width and height must be at most " + std::to_string(kMaxScreenSide);
  if (!is_valid_spp(h.spp))
    return "samples per pixel " + std::to_string(h.spp) + " is not one of 1, 2, 4, 8, 16, 32, 64";
  if (static_cast<uint8_t>(h.depth_mode) > 1) return "unknown depth mode";
  if (static_cast<uint8_t>(h.color_format) > 1) return "unknown colour format";
  if (static_cast<uint8_t>(h.compression) > 1) return "unknown compression";
  for (float c : h.clear_color)
    if (!std::isfinite(c) || c < 0.0f) return "clear colour must be finite and non-negative";
  if (!(h.clear_depth >= 0.0f && h.clear_depth <= 1.0f)) return "clear depth must be in [0, 1]";
  if (h.scene_name.size() > 65535) return "scene name longer than 65535 bytes";
  if (!is_valid_utf8(h.scene_name)) return "scene name is not valid UTF-8";
  return h.draws.validate();
}

std::string validate_fragment(const TraceHeader& h, const Fragment& f) {
  if (!h.draws.empty() && !h.draws.find(f.draw_id))
    return "draw " + std::to_string(f.draw_id) + " has no state in the header's draw table (" +
           std::to_string(h.draws.size()) + " states)";
  if (f.x >= h.width || f.y >= h.height)
    return "pixel (" + std::to_string(f.x) + ", " + std::to_string(f.y) + ") is outside the " +
           std::to_string(h.width) + "x" + std::to_string(h.height) + " screen";
  if (f.coverage == 0) return "empty coverage mask";
  if (h.spp < 64 && (f.coverage >> h.spp) != 0)
    return "coverage mask sets bits beyond " + std::to_string(h.spp) + " samples";
  if (h.depth_mode == DepthMode::kPlane) {
    if (!std::isfinite(f.z0) || !std::isfinite(f.dzdx) || !std::isfinite(f.dzdy)) return "depth plane is not finite";
  } else {
    for (uint64_t m = f.coverage; m; m &= m - 1) {
      float z = f.z[__builtin_ctzll(m)];
      if (!(z >= 0.0f && z <= 1.0f))
        return "depth of sample " + std::to_string(__builtin_ctzll(m)) + " is not in [0, 1]";
    }
  }
  for (float c : f.rgb)
    if (!std::isfinite(c) || c < 0.0f) return "colour is not finite and non-negative";
  if (!(f.alpha >= 0.0f && f.alpha <= 1.0f)) return "opacity is not in [0, 1]";
  return "";
}

size_t fragment_record_bytes(const TraceHeader& h, int covered) {
  size_t depth = h.depth_mode == DepthMode::kPlane ? 12 : 4 * size_t(covered);
  size_t colour = h.color_format == ColorFormat::kRgbF32 ? 12 : 3;
  return 1 + 4 + 4 + 2 + 2 + coverage_bytes(h.spp) + depth + colour + 4;
}

void fragment_sample_depths(const TraceHeader& h, const Fragment& f, float* z_out) {
  float ox[64], oy[64];
  for (int i = 0; i < h.spp; ++i) {
    ox[i] = sample_offset(h.positions[size_t(i)].x);
    oy[i] = sample_offset(h.positions[size_t(i)].y);
  }
  for_each_sample_depth(f.coverage, h.depth_mode == DepthMode::kPlane, f.z0, f.dzdx, f.dzdy, ox, oy, f.z.data(),
                        [z_out](int i, float z) { z_out[i] = z; });
}

}  // namespace ropsim
