// The rows of the RTL test vectors, written once: each unit's CSV header
// and row, and the $readmemh hex form of a CSV. The random vectors
// (vectors.cpp) and the vectors captured from a trace (trace_vectors.cpp)
// both format their rows here.
#pragma once
#include <cstdint>
#include <string>

#include "rtl_models/algo/tracker.h"
#include "util/hex.h"

namespace ropsim::vector_rows {

inline constexpr const char* kAlphaRefHeader = "sample_id,pixel_id,surface_id,spp,hash_bits,index_hex,ref_hex\n";
inline constexpr const char* kTrackerHeader =
    "spp,surface_id_bits,covered_in_hex,surface_id_in,surviving_hex,new_surface,n,surface_id_out,covered_out_hex\n";
inline constexpr const char* kSorterHeader = "spp,surviving_hex,stored_depths_hex,order\n";
inline constexpr const char* kDepthTestHeader =
    "spp,coverage_hex,z0_hex,dzdx_hex,dzdy_hex,stored_depths_hex,sample_depths_hex,pass_hex\n";
inline constexpr const char* kOpacityHeader = "alpha_bits,hash_bits,a_fixed_hex,ref_hex,pass\n";
inline constexpr const char* kHilbertHeader = "order,x,y,d_hex\n";

std::string hexf(float f);

std::string alpha_ref_row(uint32_t sample_id, uint64_t pixel_id, uint32_t surface_id, uint32_t spp, int hash_bits,
                          uint32_t index, uint32_t ref);
std::string tracker_row(int spp, int surface_id_bits, const TrackerState& in, uint64_t surviving, const TrackResult& r,
                        const TrackerState& out);
std::string join_hex_depths(const float* d, int spp);
std::string sorter_row(int spp, uint64_t surviving, const float* stored, const uint8_t* order, int m);
/// z[i] is read for the covered samples only (the others are "-").
std::string depth_test_row(int spp, uint64_t coverage, float z0, float dzdx, float dzdy, const float* stored,
                           const float* z, uint64_t pass);
std::string opacity_row(int alpha_bits, int hash_bits, uint64_t a_fixed, uint32_t ref, bool pass);
std::string hilbert_row(int order, uint32_t x, uint32_t y, uint64_t d);

/// The comment block that opens unit's hex file: the word width and each
/// field's bits.
std::string hex_comment(const std::string& unit);
/// One CSV row (no newline) of unit as its $readmemh word: the first column
/// in the most significant digits; a list's element i at [lo + i * bits +: bits].
std::string hex_word(const std::string& unit, const std::string& row);
/// The CSV rows of `unit` as $readmemh words: the comment block, then one
/// line per vector.
std::string csv_to_hex(const std::string& unit, const std::string& csv);

}  // namespace ropsim::vector_rows
