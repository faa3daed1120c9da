// The bytes of a trace file (docs/trace-format.md): the header's fixed
// layout, the draw table's records, and the byte streams a reader and a
// writer move the fragment records through (plain or zstd). Shared by
// trace_reader.cpp and trace_writer.cpp.
#pragma once
#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "rtl_models/algo/bits.h"
#include "traces/format/trace.h"
#include "util/errors.h"

namespace ropsim {

inline constexpr size_t kFixedHeaderBytes = 48;
inline constexpr size_t kHeaderCountOffset = 42;  ///< reserved bytes 42..47: fragment count + 1 (0: not recorded)
inline constexpr size_t kIoChunk = 1 << 17;

inline int coverage_bytes(int spp) { return int(ceil_div(unsigned(spp), 8u)); }

/// Appends the draw table (section 1.5): the count, then each state's record.
void encode_draw_table(std::vector<uint8_t>& o, const DrawTable& t);
/// One draw-state record of the table (kDrawRecordFixedBytes and its name).
DrawState decode_draw_record(const uint8_t* r);

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

/// An error inside the byte stream; TraceReader::next adds the file and record.
class SourceError : public UserError {
 public:
  using UserError::UserError;
};

/// The fragment records of a file open at their first byte: read as they
/// are (Compression::kNone) or through zstd, decoded ahead on a thread of
/// its own (decode_ahead: a core is spare for it) or as they are read. The
/// FILE stays the caller's.
std::unique_ptr<ByteSource> open_record_source(FILE* f, Compression c, bool decode_ahead = true);
/// Writes to f (path names it in errors): as given, or through zstd at
/// zstd_level on zstd_workers threads of zstd's own (0: this thread). The
/// FILE stays the caller's.
std::unique_ptr<ByteSink> open_record_sink(FILE* f, const std::string& path, Compression c, int zstd_level = 0,
                                           int zstd_workers = 0);

}  // namespace ropsim
