// ropsim fragment trace format v1 (docs/trace-format.md): what a rasterizer
// hands the ROP, in API order. Reader and writer stream: memory does not grow
// with the trace length. No SystemC here.
#pragma once
#include <array>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>

namespace ropsim {

inline constexpr char kTraceMagic[8] = {'R', 'O', 'P', 'T', 'R', 'A', 'C', 'E'};
inline constexpr uint16_t kTraceVersion = 1;
inline constexpr uint32_t kMaxScreenSide = 32768;
inline constexpr uint8_t kTagFragment = 0x01;
inline constexpr uint8_t kTagEnd = 0xFF;

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

/// A user-facing trace error: one line naming the file and the record.
class TraceError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Validates a header; returns "" when valid, otherwise the reason.
std::string validate_header(const TraceHeader& h);
/// Validates one fragment against its header; returns "" or the reason.
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
  explicit TraceReader(const std::string& path);
  ~TraceReader();
  TraceReader(const TraceReader&) = delete;
  TraceReader& operator=(const TraceReader&) = delete;

  const TraceHeader& header() const { return header_; }
  const std::string& path() const { return path_; }
  /// Reads the next fragment; false at the end record. Throws TraceError.
  bool next(Fragment& f);
  /// Records read so far (the index of the next record).
  uint64_t records_read() const { return records_; }
  /// Bytes of record data read so far (after decompression).
  uint64_t payload_bytes() const;

 private:
  [[noreturn]] void fail(const std::string& what) const;
  void read_exact(void* dst, size_t n, const char* what);

  std::string path_;
  TraceHeader header_;
  std::unique_ptr<ByteSource> src_;
  FILE* file_ = nullptr;
  uint64_t records_ = 0;
  bool ended_ = false;
};

/// Writes a trace through an OutputFile (util/output_file.h): a unique
/// temporary file renamed onto PATH on finish() after every write succeeded
/// (or a FIFO / device written in place). A writer destroyed without finish()
/// removes the temporary file, so a failed run leaves no partial output. A
/// write error (full disk, file size limit) throws UserError "PATH: reason".
class TraceWriter {
 public:
  TraceWriter(const std::string& path, const TraceHeader& header, int zstd_level = 3);
  ~TraceWriter();
  TraceWriter(const TraceWriter&) = delete;
  TraceWriter& operator=(const TraceWriter&) = delete;

  /// Validates and appends one fragment. Throws TraceError on an invalid one.
  void write(const Fragment& f);
  void finish();
  uint64_t fragments() const { return count_; }
  uint64_t raw_bytes() const { return raw_bytes_; }

 private:
  std::string path_;
  TraceHeader header_;
  std::unique_ptr<OutputFile> out_;
  std::unique_ptr<ByteSink> sink_;
  uint64_t count_ = 0;
  uint64_t raw_bytes_ = 0;
  bool finished_ = false;
};

/// One fragment as a JSON object on one line (for `ropsim trace dump`).
std::string fragment_to_json(const TraceHeader& h, const Fragment& f, uint64_t index);
std::string header_to_json(const TraceHeader& h);

}  // namespace ropsim
