// ropsim fragment trace format, versions 1 and 2 (docs/trace-format.md): what
// a rasterizer hands the ROP, in API order; version 2 adds the draw states. Reader and writer stream: memory does not
// grow with the trace length. No SystemC here.
#pragma once
#include <array>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "traces/format/draw_state.h"
#include "util/errors.h"
#include "util/memory_budget.h"

namespace ropsim {

inline constexpr char kTraceMagic[8] = {'R', 'O', 'P', 'T', 'R', 'A', 'C', 'E'};
/// The version of a trace without draw states (every trace whose
/// TraceHeader::draws is empty is written as version 1, byte for byte).
inline constexpr uint16_t kTraceVersion = 1;
/// The version of a trace with draw states: version 1's header followed, after
/// the scene name, by the draw table (section 1.5).
inline constexpr uint16_t kTraceVersionDraws = 2;
/// A draw-state record's bytes before its name (section 1.5): draw id (4),
/// flags (1), nine enumeration, mask and encoding bytes, blend colour (16),
/// name length (1).
inline constexpr size_t kDrawRecordFixedBytes = 31;
/// The draw record's flags byte: bit 0 blend, bit 1 depth test, bit 2 depth write.
inline constexpr uint8_t kDrawFlagBlend = 0x01, kDrawFlagDepthTest = 0x02, kDrawFlagDepthWrite = 0x04;
inline constexpr uint8_t kDrawKnownFlags = kDrawFlagBlend | kDrawFlagDepthTest | kDrawFlagDepthWrite;
inline constexpr uint32_t kMaxScreenSide = 32768;
inline constexpr uint8_t kTagFragment = 0x01;
inline constexpr uint8_t kTagChecksum = 0x02;
inline constexpr uint8_t kTagEnd = 0xFF;
/// Header flags (u16 at offset 10). Bit 0: the payload is checksummed (section 2.3).
inline constexpr uint16_t kTraceFlagChecksum = 0x0001;
/// Bit 1: the header is followed by its check, the XXH3-64 of every header
/// byte before it (section 1.4), so that the fragment count (bytes 42..47),
/// which the payload's checksums do not cover, is verified at open.
inline constexpr uint16_t kTraceFlagHeaderCheck = 0x0002;
inline constexpr uint16_t kTraceKnownFlags = kTraceFlagChecksum | kTraceFlagHeaderCheck;
/// The header check: a u64 right after the scene name (version 2: after the draw table).
inline constexpr size_t kHeaderCheckBytes = 8;
/// A zstd payload decompresses to at most this many bytes per compressed byte
/// (RFC 8878: a block holds at most 128 KiB, and the densest block, an RLE
/// block, takes 4 bytes: a 3-byte block header and the byte repeated).
inline constexpr uint64_t kZstdMaxRatio = 32768;
/// Checksummed payloads: the writer closes a block before it would exceed this
/// many record bytes; a reader accepts blocks of 1 .. kMaxChecksumBlockBytes.
inline constexpr uint32_t kChecksumBlockBytes = 65536;
inline constexpr uint32_t kMaxChecksumBlockBytes = 1u << 20;
/// A checksum record: tag, u32 block length, u64 XXH3-64 of the block.
inline constexpr size_t kChecksumRecordBytes = 13;

enum class DepthMode : uint8_t { kPerSample = 0, kPlane = 1 };
enum class ColorFormat : uint8_t { kRgbF32 = 0, kRgbUnorm8 = 1 };
enum class Compression : uint8_t { kNone = 0, kZstd = 1 };

const char* to_string(DepthMode m);
const char* to_string(ColorFormat f);
const char* to_string(Compression c);

/// A sample position in 1/256 pixel units from the pixel's top-left corner.
struct SamplePos {
  uint8_t x = 128, y = 128;
};

struct TraceHeader {
  uint32_t width = 0, height = 0;
  int spp = 1;
  DepthMode depth_mode = DepthMode::kPlane;
  ColorFormat color_format = ColorFormat::kRgbF32;
  Compression compression = Compression::kZstd;
  std::array<float, 3> clear_color{0.0f, 0.0f, 0.0f};  ///< linear RGB of the cleared buffer
  float clear_depth = 1.0f;
  std::array<SamplePos, 64> positions{};  ///< first spp entries are used
  std::string scene_name;
  /// Header flag bit 0: the fragment records are grouped into blocks, each
  /// preceded by a checksum record (XXH3-64). The writer's default; a writer
  /// that checksums the payload also checks the header (flag bit 1), so that
  /// unset gives the layout every version 1 reader reads.
  bool checksummed = true;
  /// Version 2: the draw states (draw_state.h), written after the scene name.
  /// Empty (every version 1 trace): each draw has default_draw_state(). The
  /// writer writes version 2 exactly when it is not empty.
  DrawTable draws;
  /// The format version this header is written as: 1 without draw states, 2 with.
  uint16_t version() const { return draws.empty() ? kTraceVersion : kTraceVersionDraws; }
};

/// One fragment: a pixel's worth of samples from one primitive.
struct Fragment {
  uint32_t draw_id = 0;
  uint32_t prim_id = 0;
  uint16_t x = 0, y = 0;
  uint64_t coverage = 0;  ///< bit i = sample i covered
  // kPlane: depth = z0 + dzdx*ox + dzdy*oy (docs/numerics.md); kPerSample: z[i].
  float z0 = 0.0f, dzdx = 0.0f, dzdy = 0.0f;
  std::array<float, 64> z{};  ///< per-sample depth, valid for covered samples (kPerSample)
  std::array<float, 3> rgb{};
  float alpha = 1.0f;
};

/// The most bytes one fragment record takes (64 samples' depths, f32 colour).
inline constexpr size_t kMaxFragmentRecordBytes = 1 + 12 + 8 + 4 * 64 + 16;

/// One fragment record's bytes (its tag first), exactly as TraceWriter::write
/// writes it, into `out` (kMaxFragmentRecordBytes at least), after checking
/// `f` with validate_fragment(). Returns the record's size, or 0 with
/// `error` set. Safe to call from several threads.
size_t encode_fragment_record(const TraceHeader& h, const Fragment& f, uint8_t* out, std::string& error);

/// A user-facing trace error: one line naming the file and the record.
class TraceError : public UserError {
 public:
  using UserError::UserError;
};

/// Validates a header; returns "" when valid, otherwise the reason.
std::string validate_header(const TraceHeader& h);
/// Validates one fragment against its header (its draw_id among the draw
/// states when the table is not empty); returns "" or the reason.
std::string validate_fragment(const TraceHeader& h, const Fragment& f);

/// Bytes of one fragment record before compression (tag byte included).
size_t fragment_record_bytes(const TraceHeader& h, int covered_samples);

/// Per-sample depths of the covered samples of f (docs/numerics.md): the plane
/// evaluated with plane_depth(), or the stored depths canonicalised.
void fragment_sample_depths(const TraceHeader& h, const Fragment& f, float* z_out);

class ByteSource;
class ByteSink;
class OutputFile;

/// Streams a trace file. Every record is validated as it is read.
class TraceReader {
 public:
  /// decode_ahead: a zstd payload is decoded on a thread of its own, ahead
  /// of the records read (open_record_source); false where the reader's
  /// caller keeps every core busy.
  explicit TraceReader(const std::string& path, bool decode_ahead = true);
  ~TraceReader();
  TraceReader(const TraceReader&) = delete;
  TraceReader& operator=(const TraceReader&) = delete;

  const TraceHeader& header() const { return header_; }
  const std::string& path() const { return path_; }
  /// Reads the next fragment; false at the end record. Throws TraceError.
  bool next(Fragment& f);
  /// Records read so far (the index of the next record).
  uint64_t records_read() const { return records_; }
  /// Bytes of fragment and end records read so far (after decompression;
  /// checksum records not included).
  uint64_t payload_bytes() const;
  /// Checksummed blocks read and verified so far.
  uint64_t blocks_read() const { return blocks_; }
  /// The number of fragments the header records (reserved bytes 42..47:
  /// count + 1), or none when they are 0 (not recorded). The reader holds
  /// the payload to it: more records, or an end record counting otherwise,
  /// is an error. A count the payload cannot hold (given the file's size)
  /// is refused at open.
  std::optional<uint64_t> recorded_fragments() const { return recorded_fragments_; }
  /// The header carries its check (flag bit 1), verified at open.
  bool header_checked() const { return header_checked_; }
  /// The version the file declares (1 or 2).
  uint16_t version() const { return version_; }
  /// The share of the file's bytes read so far, in [0, 1] (read-ahead
  /// included: for progress, not for positions).
  double file_fraction() const;

 private:
  /// Reads the draw table (version 2) that starts at file byte `at` into
  /// header_.draws, and its bytes into `bytes` (for the header check).
  void read_draw_table(FILE* f, uint64_t at, bool checked, std::vector<uint8_t>& bytes);
  /// Refuses a recorded count the payload cannot hold (a regular file's size).
  void check_recorded_count(FILE* f, uint64_t header_bytes);
  [[noreturn]] void fail(const std::string& what) const;
  [[noreturn]] void fail_block(const std::string& what) const;
  void read_exact(void* dst, size_t n, const char* what);
  /// Record bytes: from the verified block (checksummed) or the payload stream.
  size_t take(void* dst, size_t n);
  /// Reads the checksum record after its tag, then the block, and verifies it.
  void load_block();
  /// Reads the end record after its tag and checks what follows it.
  void read_end();
  std::string where() const;

  std::string path_;
  TraceHeader header_;
  std::unique_ptr<ByteSource> src_;
  FILE* file_ = nullptr;
  uint64_t file_size_ = 0;
  uint64_t records_ = 0;
  bool ended_ = false;
  // Checksummed payloads: the current verified block and where it started.
  std::vector<uint8_t> block_;
  size_t block_pos_ = 0, block_len_ = 0;
  uint64_t blocks_ = 0;              ///< blocks loaded (the current one included)
  uint64_t block_first_record_ = 0;  ///< record number of the block's first record
  uint64_t block_offset_ = 0;        ///< payload byte offset of the block's checksum record
  bool at_end_record_ = false;       ///< reading the end record (errors name its position)
  std::optional<uint64_t> recorded_fragments_;
  bool header_checked_ = false;
  uint16_t version_ = kTraceVersion;
  BudgetShare draws_mem_;  ///< the draw table's bytes in the memory budget (--memory-limit)
};

/// The most fragment records a payload of payload_bytes can hold, given the
/// header (its smallest record, the end record, a checksum record when the
/// payload is checksummed). payload_bytes counts decompressed bytes.
uint64_t max_fragments_in_payload(const TraceHeader& h, uint64_t payload_bytes);

/// Writes a trace through an OutputFile (util/output_file.h): a unique
/// temporary file renamed onto PATH on finish() after every write succeeded
/// (or a FIFO / device written in place). A writer destroyed without finish()
/// removes the temporary file, so a failed run leaves no partial output. A
/// write error (full disk, file size limit) throws UserError "PATH: reason".
class TraceWriter {
 public:
  /// zstd_workers: 0 compresses on the calling thread; N > 0 on N threads of
  /// zstd's own (ZSTD_c_nbWorkers), overlapping the records' encoding. The
  /// payload bytes depend on the level and the worker count (0, or any N),
  /// never on the timing: a fixed count gives the same trace every run.
  TraceWriter(const std::string& path, const TraceHeader& header, int zstd_level = 3, int zstd_workers = 0);
  /// The header last: for a writer that learns the draw table while it
  /// writes the records. The records are framed and compressed into memory
  /// as they come, as `layout` says (size, spp, depth mode, colour format,
  /// compression, checksums), and finish(header) writes PATH: `header` (the
  /// same layout; its draw table, clear values and scene name as they end
  /// up), then those records. The file is byte for byte the one
  /// TraceWriter(path, header) writes from the same records.
  struct HeaderLast {};
  TraceWriter(const std::string& path, const TraceHeader& layout, int zstd_level, int zstd_workers, HeaderLast);
  ~TraceWriter();
  TraceWriter(const TraceWriter&) = delete;
  TraceWriter& operator=(const TraceWriter&) = delete;

  /// Validates and appends one fragment. Throws TraceError on an invalid one.
  void write(const Fragment& f);
  /// Appends `count` fragment records that encode_fragment_record() made
  /// (`bytes` of them, back to back): the same trace as write() of each
  /// fragment. Their framing is checked (tags, each record's length from its
  /// coverage); their fields were checked when they were encoded. Throws
  /// TraceError on a record that does not frame.
  void write_records(const uint8_t* records, size_t bytes, uint64_t count);
  void finish();
  /// A header-last writer's end: the file with `header` (its layout must be
  /// the one given at the start; TraceError otherwise).
  void finish(const TraceHeader& header);
  uint64_t fragments() const { return count_; }
  /// Bytes of fragment and end records written (checksum records not included).
  uint64_t raw_bytes() const { return raw_bytes_; }
  /// Checksummed blocks written so far.
  uint64_t blocks() const { return blocks_; }

 private:
  void flush_block();
  /// Flushes the last block, writes the end record and closes the record stream.
  void end_records();
  /// Appends encoded records (whole ones, `n` bytes) to the payload.
  void append_records(const uint8_t* b, size_t n);

  std::string path_;
  TraceHeader header_;
  std::unique_ptr<OutputFile> out_;
  std::unique_ptr<ByteSink> sink_;
  uint64_t count_ = 0;
  uint64_t raw_bytes_ = 0;
  uint64_t blocks_ = 0;
  std::vector<uint8_t> block_;  ///< the block being gathered (checksummed traces)
  std::vector<uint8_t> head_;   ///< the header's bytes, its check excluded (patched by finish())
  bool finished_ = false;
  /// Header last: the payload's stream and the memory it gathers in.
  struct Payload;
  std::unique_ptr<Payload> payload_bytes_;
  FILE* payload_ = nullptr;
};

/// One fragment as a JSON object on one line (for `ropsim trace dump`).
std::string fragment_to_json(const TraceHeader& h, const Fragment& f, uint64_t index);
/// The header as one JSON object: its fields, the version it is written as and
/// the draw table ("draws": draw_state_to_json() of each state; [] for none).
std::string header_to_json(const TraceHeader& h);
/// One draw state as a JSON object: its fields by name (GL's enumerant names
/// without GL_) and its kind (draw_kind()).
std::string draw_state_to_json(const DrawState& s);

}  // namespace ropsim
