// The live-point library file (`ropsim livepoints`, docs/livepoints.md): one
// functional pass's live-points, with the golden image and counters, written
// once and read by every `run --fidelity sampled --livepoints LIB` of a design
// sweep, so that no design pays the functional pass again.
//
// The file is a fixed header (magic, version, the payload's size and its
// XXH3-64) and the payload, one zstd frame. The payload is written field by
// field, little-endian, in a fixed order: the same library gives the same
// bytes. A library is refused for any input but its own (the input's digest,
// input_digest) and for a different method or numerics.
#pragma once
#include <string>
#include <vector>

#include "rtl_models/functional/fragment_source.h"
#include "sim/fidelity/sampled/livepoints.h"

namespace ropsim {

/// The library format's version (docs/livepoints.md).
inline constexpr uint32_t kLivePointFileVersion = 4;

/// Zeroes what a fragment's trace record does not carry (the per-sample
/// depths of a plane-mode trace, those of uncovered samples and past spp), so
/// that a fragment read back from a library equals the one recorded, bit for
/// bit, however the reader reused its slots.
void canonicalise(const TraceHeader& h, Fragment& f);

/// What identifies the input: a trace file by the XXH3-64 of its bytes, a
/// built-in scene by the XXH3-64 of its header and fragment stream. Throws
/// UserError / TraceError / SceneError for an unreadable input.
InputIdentity input_identity(const InputSpec& in);

/// Writes lib to path through an OutputFile (all or nothing). Throws UserError.
void write_livepoints(const std::string& path, const LivePoints& lib);

/// Reads a library. Throws UserError "PATH: ..." for a file that is not one,
/// of another version, truncated or corrupt (the checksum), or over the
/// memory limit.
LivePoints read_livepoints(const std::string& path);

/// A library file around payload bytes (the header, the checksum and the zstd
/// frame): for the fuzz target, which reaches the payload's parser this way.
std::vector<uint8_t> wrap_livepoint_payload(const uint8_t* payload, size_t size);

/// Throws UserError unless in is the input lib was recorded from (its digest).
void check_library_input(const LivePoints& lib, const std::string& lib_path, const InputSpec& in);

/// Throws UserError naming the first field of method that differs from the
/// library's (a library serves one method and its numerics).
void check_library_method(const LivePoints& lib, const std::string& lib_path, const MethodConfig& method);

/// Throws UserError naming the first sampling parameter (K, U, W, C, T, R)
/// of p that differs from the library's (a library is one sampling's).
void check_library_sampling(const LivePoints& lib, const std::string& lib_path, const SamplingParams& p);

}  // namespace ropsim
