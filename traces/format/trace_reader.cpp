// Reading a trace file, versions 1 and 2 (docs/trace-format.md).
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

TraceReader::TraceReader(const std::string& path, bool decode_ahead) : path_(path) {
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
  src_ = open_record_source(f, h.compression, decode_ahead);
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
    f.coverage = get_le(b + 12, cb);
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

}  // namespace ropsim
