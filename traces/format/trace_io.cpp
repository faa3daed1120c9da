// Trace reader and writer, versions 1 and 2 (docs/trace-format.md).
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
#include "traces/format/utf8.h"
#include "util/errors.h"
#include "util/output_file.h"

namespace ropsim {

const char* to_string(DepthMode m) { return m == DepthMode::kPlane ? "plane" : "per-sample"; }
const char* to_string(ColorFormat f) { return f == ColorFormat::kRgbF32 ? "rgb-f32" : "rgb-unorm8"; }
const char* to_string(Compression c) { return c == Compression::kZstd ? "zstd" : "none"; }

namespace {

constexpr size_t kFixedHeaderBytes = 48;
constexpr size_t kHeaderCountOffset = 42;  ///< reserved bytes 42..47: fragment count + 1 (0: not recorded)
constexpr size_t kIoChunk = 1 << 17;

void put_u16(uint8_t* p, uint16_t v) {
  p[0] = uint8_t(v);
  p[1] = uint8_t(v >> 8);
}
void put_u32(uint8_t* p, uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = uint8_t(v >> (8 * i));
}
void put_u64(uint8_t* p, uint64_t v) {
  for (int i = 0; i < 8; ++i) p[i] = uint8_t(v >> (8 * i));
}
void put_u48(uint8_t* p, uint64_t v) {
  for (int i = 0; i < 6; ++i) p[i] = uint8_t(v >> (8 * i));
}
void put_f32(uint8_t* p, float f) {
  uint32_t v;
  std::memcpy(&v, &f, 4);
  put_u32(p, v);
}
uint16_t get_u16(const uint8_t* p) { return uint16_t(p[0] | (p[1] << 8)); }
uint32_t get_u32(const uint8_t* p) {
  return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24;
}
uint64_t get_u64(const uint8_t* p) { return uint64_t(get_u32(p)) | uint64_t(get_u32(p + 4)) << 32; }
uint64_t get_u48(const uint8_t* p) { return uint64_t(get_u32(p)) | uint64_t(get_u16(p + 4)) << 32; }
float get_f32(const uint8_t* p) {
  uint32_t v = get_u32(p);
  float f;
  std::memcpy(&f, &v, 4);
  return f;
}

int coverage_bytes(int spp) { return int(ceil_div(unsigned(spp), 8u)); }

/// Appends the draw table (section 1.5): the count, then each state's record.
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

}  // namespace

// ---------------------------------------------------------------- byte I/O

class ByteSource {
 public:
  virtual ~ByteSource() = default;
  /// Reads up to n bytes; returns fewer only at the end of the data.
  virtual size_t read(void* dst, size_t n) = 0;
  /// True when the data ended cleanly (a compressed stream ended with its frame complete).
  virtual bool complete() const { return true; }
  uint64_t consumed = 0;
};

class ByteSink {
 public:
  virtual ~ByteSink() = default;
  virtual void write(const void* src, size_t n) = 0;
  virtual void close() = 0;
};

namespace {

/// An error inside the byte stream; TraceReader::next adds the file and record.
class SourceError : public UserError {
 public:
  using UserError::UserError;
};

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

class ZstdSource : public ByteSource {
 public:
  explicit ZstdSource(FILE* f) : f_(f), in_(kIoChunk), out_(kIoChunk) {
    ds_ = ZSTD_createDStream();
    ZSTD_initDStream(ds_);
  }
  ~ZstdSource() override { ZSTD_freeDStream(ds_); }
  size_t read(void* dst, size_t n) override {
    uint8_t* d = static_cast<uint8_t*>(dst);
    size_t done = 0;
    while (done < n) {
      if (out_pos_ < out_len_) {
        size_t k = std::min(n - done, out_len_ - out_pos_);
        std::memcpy(d + done, out_.data() + out_pos_, k);
        out_pos_ += k;
        done += k;
        continue;
      }
      if (!refill()) break;
    }
    consumed += done;
    return done;
  }
  bool complete() const override { return frame_done_; }

 private:
  bool refill() {
    for (;;) {
      if (in_pos_ == in_len_ && !eof_) {
        in_len_ = std::fread(in_.data(), 1, in_.size(), f_);
        in_pos_ = 0;
        if (in_len_ == 0) eof_ = true;
      }
      if (frame_done_) {
        // The payload is exactly one zstd frame: bytes after it are not trace data.
        if (in_pos_ < in_len_) throw SourceError("data after the end of the compressed frame");
        return false;
      }
      // At the end of the file the decoder may still hold decoded data: call it
      // with empty input until it has nothing more to give.
      ZSTD_inBuffer ib{in_.data(), in_len_, in_pos_};
      ZSTD_outBuffer ob{out_.data(), out_.size(), 0};
      size_t r = ZSTD_decompressStream(ds_, &ob, &ib);
      in_pos_ = ib.pos;
      if (ZSTD_isError(r)) throw SourceError(std::string("corrupt compressed data: ") + ZSTD_getErrorName(r));
      frame_done_ = r == 0;  // 0: the frame is complete (checksum verified) and fully flushed
      out_len_ = ob.pos;
      out_pos_ = 0;
      if (out_len_ > 0) return true;
      if (eof_ && in_pos_ == in_len_) return false;  // truncated frame: complete() stays false
    }
  }
  FILE* f_;
  ZSTD_DStream* ds_;
  std::vector<uint8_t> in_, out_;
  size_t in_pos_ = 0, in_len_ = 0, out_pos_ = 0, out_len_ = 0;
  bool eof_ = false;
  bool frame_done_ = false;
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

// ---------------------------------------------------------------- validation

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

// ---------------------------------------------------------------- reader

TraceReader::TraceReader(const std::string& path) : path_(path) {
  FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) throw TraceError(path + ": cannot open: " + std::strerror(errno));
  std::unique_ptr<FILE, int (*)(FILE*)> guard(f, &std::fclose);
  uint8_t fixed[kFixedHeaderBytes];
  size_t got = std::fread(fixed, 1, sizeof fixed, f);
  if (std::memcmp(fixed, kTraceMagic, std::min<size_t>(got, 8)) != 0)
    throw TraceError(path + ": header: not a ropsim trace (bad magic)");
  if (got < sizeof fixed) throw TraceError(path + ": header: truncated (" + std::to_string(got) + " of 48 bytes)");
  const uint16_t version = get_u16(fixed + 8);
  if (version != kTraceVersion && version != kTraceVersionDraws)
    throw TraceError(path + ": header: unsupported version " + std::to_string(version) +
                     " (this reader reads 1 and 2)");
  version_ = version;
  const uint16_t flags = get_u16(fixed + 10);
  if (flags & ~kTraceKnownFlags) {
    char hex[8];
    std::snprintf(hex, sizeof hex, "0x%04x", unsigned(flags & ~kTraceKnownFlags));
    throw TraceError(path + ": header: unknown flags " + hex +
                     " (this reader knows bit 0, checksummed payload, and bit 1, header check)");
  }
  if (version == kTraceVersionDraws && (flags & kTraceFlagChecksum) && !(flags & kTraceFlagHeaderCheck))
    throw TraceError(path +
                     ": header: a version 2 trace with a checksummed payload (flag bit 0) must check its header "
                     "(flag bit 1), which covers the draw table");
  TraceHeader& h = header_;
  h.checksummed = (flags & kTraceFlagChecksum) != 0;
  h.width = get_u32(fixed + 12);
  h.height = get_u32(fixed + 16);
  h.spp = fixed[20];
  h.depth_mode = static_cast<DepthMode>(fixed[21]);
  h.color_format = static_cast<ColorFormat>(fixed[22]);
  h.compression = static_cast<Compression>(fixed[23]);
  for (int i = 0; i < 3; ++i) h.clear_color[i] = get_f32(fixed + 24 + 4 * i);
  h.clear_depth = get_f32(fixed + 36);
  uint16_t name_len = get_u16(fixed + 40);
  if (const uint64_t recorded = get_u48(fixed + kHeaderCountOffset)) recorded_fragments_ = recorded - 1;
  std::string err = validate_header(h);
  if (!err.empty()) throw TraceError(path + ": header: " + err);
  uint8_t pos[128];
  if (std::fread(pos, 1, 2 * size_t(h.spp), f) != 2 * size_t(h.spp))
    throw TraceError(path + ": header: truncated in the sample positions");
  for (int i = 0; i < h.spp; ++i) h.positions[i] = SamplePos{pos[2 * i], pos[2 * i + 1]};
  h.scene_name.resize(name_len);
  if (name_len && std::fread(h.scene_name.data(), 1, name_len, f) != name_len)
    throw TraceError(path + ": header: truncated in the scene name");
  if (!is_valid_utf8(h.scene_name)) throw TraceError(path + ": header: scene name is not valid UTF-8");
  uint64_t header_bytes = kFixedHeaderBytes + 2 * size_t(h.spp) + name_len;
  struct stat sb;
  if (::fstat(fileno(f), &sb) == 0 && S_ISREG(sb.st_mode) && sb.st_size > 0) file_size_ = uint64_t(sb.st_size);
  std::vector<uint8_t> table;  // version 2: the draw table's bytes as read (the header check covers them)
  if (version == kTraceVersionDraws) {
    read_draw_table(f, header_bytes, (flags & kTraceFlagHeaderCheck) != 0, table);
    header_bytes += table.size();
  }
  if (flags & kTraceFlagHeaderCheck) {
    // The check covers every header byte before it: the fixed part, the
    // positions, the name and (version 2) the draw table, as read.
    uint8_t c[kHeaderCheckBytes];
    if (std::fread(c, 1, sizeof c, f) != sizeof c) throw TraceError(path + ": header: truncated in the header check");
    std::vector<uint8_t> head(fixed, fixed + sizeof fixed);
    head.insert(head.end(), pos, pos + 2 * size_t(h.spp));
    head.insert(head.end(), h.scene_name.begin(), h.scene_name.end());
    head.insert(head.end(), table.begin(), table.end());
    const uint64_t stored = get_u64(c), computed = XXH3_64bits(head.data(), head.size());
    if (stored != computed) {
      char m[160];
      std::snprintf(m, sizeof m,
                    ": header: header check mismatch (stored 0x%016" PRIx64 ", computed 0x%016" PRIx64
                    "): a header byte, the fragment count (bytes 42..47) included, is damaged",
                    stored, computed);
      throw TraceError(path + m);
    }
    header_checked_ = true;
    header_bytes += kHeaderCheckBytes;
  }
  if (recorded_fragments_ && file_size_ > 0) check_recorded_count(f, header_bytes);
  std::setvbuf(f, nullptr, _IOFBF, kIoChunk);
  if (h.compression == Compression::kZstd)
    src_ = std::make_unique<ZstdSource>(f);
  else
    src_ = std::make_unique<FileSource>(f);
  guard.release();
  file_ = f;
}

void TraceReader::read_draw_table(FILE* f, uint64_t at, bool checked, std::vector<uint8_t>& bytes) {
  const std::string where = path_ + ": header: ";
  uint8_t c[4];
  if (std::fread(c, 1, sizeof c, f) != sizeof c) throw TraceError(where + "truncated in the draw count");
  bytes.assign(c, c + 4);
  const uint32_t n = get_u32(c);
  const uint64_t per_state = sizeof(DrawState) + kDrawRecordFixedBytes;  // the state and its record's bytes
  if (file_size_ > 0) {
    // A regular file: the count is bounded by what follows it, n records of
    // kDrawRecordFixedBytes or more, the header check and the end record.
    const uint64_t after = at + 4 + (checked ? kHeaderCheckBytes : 0) + 9;
    const uint64_t room = file_size_ > after ? file_size_ - after : 0, most = room / kDrawRecordFixedBytes;
    if (n > most)
      throw TraceError(where + "draw count " + std::to_string(n) + " is more than the file's " + std::to_string(room) +
                       " bytes after it can hold (at most " + std::to_string(most) + " records of " +
                       std::to_string(kDrawRecordFixedBytes) +
                       " bytes or more): the header is damaged or the file truncated");
    draws_mem_.add(n * per_state, "the draw table of " + path_);
    bytes.reserve(4 + size_t(n) * kDrawRecordFixedBytes);
  }
  std::vector<DrawState> states;
  if (file_size_ > 0) states.reserve(n);
  for (uint32_t i = 0; i < n; ++i) {
    const std::string rec = "draw state " + std::to_string(i);
    uint8_t r[kDrawRecordFixedBytes];
    if (std::fread(r, 1, sizeof r, f) != sizeof r) throw TraceError(where + "truncated in " + rec);
    DrawState s = decode_draw_record(r);
    const std::string at_rec = rec + " (draw " + std::to_string(s.draw_id) + "): ";
    if (r[4] & ~kDrawKnownFlags) {
      char hex[8];
      std::snprintf(hex, sizeof hex, "0x%02x", unsigned(r[4] & ~kDrawKnownFlags));
      throw TraceError(where + at_rec + "unknown flags " + hex +
                       " (bit 0 blend, bit 1 depth test, bit 2 depth write; the others are 0)");
    }
    if (!states.empty() && s.draw_id < states.back().draw_id)
      throw TraceError(where + at_rec + "draw ids out of order (after draw " + std::to_string(states.back().draw_id) +
                       "; the table is sorted by draw id)");
    const uint8_t len = r[30];
    s.name.resize(len);
    if (len && std::fread(s.name.data(), 1, len, f) != len) throw TraceError(where + "truncated in " + rec + "'s name");
    draws_mem_.add((file_size_ > 0 ? 0 : per_state) + 2 * uint64_t(len), "the draw table of " + path_);
    bytes.insert(bytes.end(), r, r + sizeof r);
    bytes.insert(bytes.end(), s.name.begin(), s.name.end());
    states.push_back(std::move(s));
  }
  // The records are in draw-id order, so validate()'s "draw state i" is the
  // i-th record of the file.
  header_.draws = DrawTable(std::move(states));
  const std::string err = header_.draws.validate();
  if (!err.empty()) throw TraceError(where + err);
}

void TraceReader::check_recorded_count(FILE* f, uint64_t header_bytes) {
  const TraceHeader& h = header_;
  const uint64_t n = *recorded_fragments_;
  const uint64_t stored = file_size_ > header_bytes ? file_size_ - header_bytes : 0;
  // What the payload decompresses to at most: itself when stored as is; for
  // zstd, the content size when the frame header records it (zstd refuses a
  // frame whose content differs), else kZstdMaxRatio bytes per byte.
  uint64_t decoded = stored;
  std::string how = "the payload's " + std::to_string(stored) + " bytes";
  if (h.compression == Compression::kZstd) {
    constexpr size_t kFrameHeaderMax = 18;  // ZSTD_FRAMEHEADERSIZE_MAX
    uint8_t fh[kFrameHeaderMax];
    const off_t at = ::ftello(f);
    const size_t got = std::fread(fh, 1, sizeof fh, f);
    if (at < 0 || ::fseeko(f, at, SEEK_SET) != 0) throw TraceError(path_ + ": cannot seek: " + std::strerror(errno));
    const unsigned long long content = ZSTD_getFrameContentSize(fh, got);
    if (content != ZSTD_CONTENTSIZE_UNKNOWN && content != ZSTD_CONTENTSIZE_ERROR) {
      decoded = content;
      how = "the payload's " + std::to_string(decoded) + " bytes (the content size of its zstd frame)";
    } else {
      decoded = stored > UINT64_MAX / kZstdMaxRatio ? UINT64_MAX : stored * kZstdMaxRatio;
      how = "the compressed payload's " + std::to_string(stored) + " bytes (at most " + std::to_string(decoded) +
            " decompressed, " + std::to_string(kZstdMaxRatio) + " per compressed byte)";
    }
  }
  const uint64_t most = max_fragments_in_payload(h, decoded);
  if (n > most)
    throw TraceError(path_ + ": header: fragment count (bytes 42..47) " + std::to_string(n) + " is more than " + how +
                     " can hold (at most " + std::to_string(most) + " records of " +
                     std::to_string(fragment_record_bytes(h, 1)) +
                     " bytes or more): the header is damaged or the file truncated");
}

uint64_t max_fragments_in_payload(const TraceHeader& h, uint64_t payload_bytes) {
  constexpr uint64_t kEndRecordBytes = 9;
  if (payload_bytes < kEndRecordBytes) return 0;
  uint64_t room = payload_bytes - kEndRecordBytes;
  if (h.checksummed) {  // a fragment record lies in a block, after its checksum record
    if (room < kChecksumRecordBytes) return 0;
    room -= kChecksumRecordBytes;
  }
  return room / fragment_record_bytes(h, 1);
}

double TraceReader::file_fraction() const {
  if (ended_) return 1.0;
  if (!file_ || file_size_ == 0) return 0.0;
  const off_t at = ::ftello(file_);
  return at <= 0 ? 0.0 : std::min(1.0, double(at) / double(file_size_));
}

TraceReader::~TraceReader() {
  src_.reset();
  if (file_) std::fclose(file_);
}

uint64_t TraceReader::payload_bytes() const {
  if (!src_) return 0;
  if (!header_.checksummed) return src_->consumed;
  // Everything decoded, less the checksum records and the unread rest of the block.
  return src_->consumed - kChecksumRecordBytes * blocks_ - (block_len_ - block_pos_);
}

std::string TraceReader::where() const {
  if (at_end_record_)
    return "end record at payload byte " + std::to_string(block_offset_) + " (after " + std::to_string(blocks_) +
           " blocks)";
  return "block " + std::to_string(blocks_ ? blocks_ - 1 : 0) + " (records from " +
         std::to_string(block_first_record_) + ", payload byte " + std::to_string(block_offset_) + ")";
}

void TraceReader::fail(const std::string& what) const {
  if (header_.checksummed)
    throw TraceError(path_ + ": " + where() + ": record " + std::to_string(records_) + ": " + what);
  throw TraceError(path_ + ": record " + std::to_string(records_) + ": " + what);
}

void TraceReader::fail_block(const std::string& what) const { throw TraceError(path_ + ": " + where() + ": " + what); }

size_t TraceReader::take(void* dst, size_t n) {
  if (!header_.checksummed) return src_->read(dst, n);
  const size_t k = std::min(n, block_len_ - block_pos_);
  std::memcpy(dst, block_.data() + block_pos_, k);
  block_pos_ += k;
  return k;
}

void TraceReader::read_exact(void* dst, size_t n, const char* what) {
  if (take(dst, n) != n) {
    if (header_.checksummed) fail(std::string("the record runs past the end of its block (in the ") + what + ")");
    fail(std::string("truncated in the ") + what + " (no end record)");
  }
}

void TraceReader::load_block() {
  uint8_t b[kChecksumRecordBytes - 1];
  const size_t got_rec = src_->read(b, sizeof b);
  if (got_rec != sizeof b)
    fail_block("truncated in the checksum record (" + std::to_string(got_rec + 1) + " of " +
               std::to_string(kChecksumRecordBytes) + " bytes)");
  const uint32_t len = get_u32(b);
  const uint64_t stored = get_u64(b + 4);
  if (len == 0) fail_block("block length 0 (a block holds at least one record)");
  if (len > kMaxChecksumBlockBytes)
    fail_block("block length " + std::to_string(len) + " exceeds the limit of " +
               std::to_string(kMaxChecksumBlockBytes) + " bytes");
  if (block_.size() < len) block_.resize(len);
  const size_t got = src_->read(block_.data(), len);
  if (got != len)
    fail_block("block length " + std::to_string(len) + " runs past the end of the payload (" + std::to_string(got) +
               " bytes follow the checksum record)");
  const uint64_t computed = XXH3_64bits(block_.data(), len);
  if (computed != stored) {
    char s[96];
    std::snprintf(s, sizeof s, "checksum mismatch (stored 0x%016" PRIx64 ", computed 0x%016" PRIx64 ")", stored,
                  computed);
    fail_block(s);
  }
  block_len_ = len;
  block_pos_ = 0;
}

void TraceReader::read_end() {
  uint8_t b[8];
  if (src_->read(b, 8) != 8) fail("truncated in the end record (no end record)");
  uint64_t count = get_u64(b);
  if (count != records_)
    fail("end record counts " + std::to_string(count) + " fragments but " + std::to_string(records_) + " were read");
  if (recorded_fragments_ && *recorded_fragments_ != count)
    fail("end record counts " + std::to_string(count) + " fragments but the header records " +
         std::to_string(*recorded_fragments_));
  uint8_t extra;
  if (src_->read(&extra, 1) != 0) fail("data after the end record");
  if (!src_->complete()) fail("truncated: the compressed frame is incomplete");
  ended_ = true;
}

bool TraceReader::next(Fragment& f) {
  if (ended_) return false;
  try {
    uint8_t tag;
    if (header_.checksummed && block_pos_ == block_len_) {
      // A block boundary: a checksum record opens the next block, or the end record follows the last.
      block_first_record_ = records_;
      block_offset_ = src_->consumed;
      ++blocks_;
      if (src_->read(&tag, 1) != 1) fail_block("truncated: the trace ends without an end record");
      if (tag == kTagEnd) {
        --blocks_;
        at_end_record_ = true;
        read_end();
        return false;
      }
      if (tag != kTagChecksum)
        fail_block("expected a checksum record (tag 2) or the end record (tag 255), found tag " + std::to_string(tag));
      load_block();
    }
    if (take(&tag, 1) != 1) fail("truncated: the trace ends without an end record");
    if (header_.checksummed && tag != kTagFragment)
      fail("record tag " + std::to_string(tag) + " inside a block (a block holds only fragment records)");
    if (tag == kTagEnd) {
      read_end();
      return false;
    }
    if (tag == kTagChecksum) fail("checksum record (tag 2) in a trace whose header does not flag checksums");
    if (tag != kTagFragment) fail("unknown record tag " + std::to_string(tag));
    if (recorded_fragments_ && records_ >= *recorded_fragments_)
      fail("a fragment record beyond the " + std::to_string(*recorded_fragments_) + " the header records");
    const TraceHeader& h = header_;
    uint8_t b[16 + 8 + 256 + 12 + 4];
    const int cb = coverage_bytes(h.spp);
    // Plane records have a fixed size: read the record in one call (a short
    // read still names the part that is missing).
    const size_t head = 12 + size_t(cb);
    const bool fixed = h.depth_mode == DepthMode::kPlane;
    const size_t colour_bytes = h.color_format == ColorFormat::kRgbF32 ? 16 : 7;
    if (fixed) {
      const size_t total = head + 12 + colour_bytes;
      const size_t got = take(b, total);
      if (got != total) {
        const char* part = got < head ? "fragment" : got < head + 12 ? "depth plane" : "colour";
        if (h.checksummed) fail(std::string("the record runs past the end of its block (in the ") + part + ")");
        fail(std::string("truncated in the ") + part + " (no end record)");
      }
    } else {
      read_exact(b, head, "fragment");
    }
    f.draw_id = get_u32(b);
    f.prim_id = get_u32(b + 4);
    f.x = get_u16(b + 8);
    f.y = get_u16(b + 10);
    f.coverage = 0;
    for (int i = 0; i < cb; ++i) f.coverage |= uint64_t(b[12 + i]) << (8 * i);
    const int covered = __builtin_popcountll(f.coverage);
    const uint8_t* colour = b + head + 12;  // plane records: already read
    if (fixed) {
      f.z0 = get_f32(b + head);
      f.dzdx = get_f32(b + head + 4);
      f.dzdy = get_f32(b + head + 8);
    } else {
      read_exact(b, 4 * size_t(covered), "sample depths");
      int k = 0;
      for (uint64_t m = f.coverage; m; m &= m - 1) f.z[__builtin_ctzll(m)] = get_f32(b + 4 * k++);
      read_exact(b, colour_bytes, "colour");
      colour = b;
    }
    if (h.color_format == ColorFormat::kRgbF32) {
      for (int i = 0; i < 3; ++i) f.rgb[i] = get_f32(colour + 4 * i);
      f.alpha = get_f32(colour + 12);
    } else {
      for (int i = 0; i < 3; ++i) f.rgb[i] = colour[i] / 255.0f;
      f.alpha = get_f32(colour + 3);
    }
    std::string err = validate_fragment(h, f);
    if (!err.empty()) fail(err);
    ++records_;
    return true;
  } catch (const SourceError& e) {  // corrupt or trailing compressed data
    fail(e.what());
  }
}

// ---------------------------------------------------------------- writer

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
  FileSink raw(f, path);
  raw.write(head_.data(), head_.size());
  if (header_.checksummed) {
    uint8_t c[kHeaderCheckBytes];
    put_u64(c, XXH3_64bits(head_.data(), head_.size()));
    raw.write(c, sizeof c);
  }
  if (header_.compression == Compression::kZstd)
    sink_ = std::make_unique<ZstdSink>(f, path, zstd_level, zstd_workers);
  else
    sink_ = std::make_unique<FileSink>(f, path);
  if (header_.checksummed) block_.reserve(kChecksumBlockBytes);
}

TraceWriter::~TraceWriter() {
  sink_.reset();
  out_.reset();  // discards the temporary file unless finish() committed it
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
  for (int i = 0; i < coverage_bytes(h.spp); ++i) b[n++] = uint8_t(f.coverage >> (8 * i));
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
