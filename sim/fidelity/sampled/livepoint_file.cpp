#include "sim/fidelity/sampled/livepoint_file.h"

#include <xxhash.h>
#include <zstd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <memory>
#include <string_view>

#include "rtl_models/algo/bits.h"
#include "rtl_models/algo/half.h"
#include "sim/fidelity/sampled/livepoint_payload.h"
#include "traces/format/utf8.h"
#include "util/byte_codec.h"
#include "util/errors.h"
#include "util/hex.h"
#include "util/memory_budget.h"
#include "util/output_file.h"

namespace ropsim {

namespace {

constexpr char kMagic[8] = {'R', 'O', 'P', 'S', 'I', 'M', 'L', 'P'};
constexpr size_t kFileHeaderBytes = 8 + 4 + 4 + 8 + 8;  // magic, version, reserved, payload bytes, XXH3-64

}  // namespace

std::vector<uint8_t> wrap_livepoint_payload(const uint8_t* payload, size_t size) {
  std::vector<uint8_t> file(kFileHeaderBytes);
  std::memcpy(file.data(), kMagic, 8);
  put_le(file.data() + 8, kLivePointFileVersion, 4);
  put_le(file.data() + 12, 0, 4);
  put_le(file.data() + 16, size, 8);
  put_le(file.data() + 24, XXH3_64bits(payload, size), 8);
  std::vector<uint8_t> frame(ZSTD_compressBound(size));
  const size_t n = ZSTD_compress(frame.data(), frame.size(), payload, size, 1);
  invariant(!ZSTD_isError(n), "zstd compresses into its bound");
  file.insert(file.end(), frame.begin(), frame.begin() + std::ptrdiff_t(n));
  return file;
}

void write_livepoints(const std::string& path, const LivePoints& lib) {
  ensure_parent_dir(path);
  OutputFile out(path);
  std::unique_ptr<ZSTD_CCtx, decltype(&ZSTD_freeCCtx)> cctx(ZSTD_createCCtx(), ZSTD_freeCCtx);
  invariant(cctx != nullptr, "zstd context allocated");
  ZSTD_CCtx_setParameter(cctx.get(), ZSTD_c_compressionLevel, 3);
  // Two compression workers, whatever the host's cores: zstd's output
  // depends on the worker count (not on timing), so the file is the same on
  // every machine. A library without threads support compresses in this one.
  ZSTD_CCtx_setParameter(cctx.get(), ZSTD_c_nbWorkers, 2);
  std::vector<uint8_t> obuf(ZSTD_CStreamOutSize());
  auto compress = [&](const uint8_t* data, size_t n, ZSTD_EndDirective mode) {
    ZSTD_inBuffer in{data, n, 0};
    for (;;) {
      ZSTD_outBuffer ob{obuf.data(), obuf.size(), 0};
      const size_t left = ZSTD_compressStream2(cctx.get(), &ob, &in, mode);
      if (ZSTD_isError(left)) out.fail(std::string("compression failed: ") + ZSTD_getErrorName(left));
      out.write(obuf.data(), ob.pos);
      if (mode == ZSTD_e_end ? left == 0 : in.pos == in.size) break;
    }
  };
  uint8_t head[kFileHeaderBytes];
  std::memcpy(head, kMagic, 8);
  put_le(head + 8, kLivePointFileVersion, 4);
  put_le(head + 12, 0, 4);
  if (!out.can_patch()) {
    // A FIFO or a device cannot take the payload's size and hash afterwards:
    // the payload whole first.
    PayloadWriter p;
    encode_livepoint_payload(lib, p);
    put_le(head + 16, p.bytes().size(), 8);
    put_le(head + 24, XXH3_64bits(p.bytes().data(), p.bytes().size()), 8);
    out.write(head, sizeof head);
    compress(p.bytes().data(), p.bytes().size(), ZSTD_e_end);
    out.commit();
    return;
  }
  // Encoded, hashed and compressed a piece at a time (the workers compress
  // while this thread encodes); the size and hash go into the header last.
  out.write(head, sizeof head);
  std::unique_ptr<XXH3_state_t, decltype(&XXH3_freeState)> hash(XXH3_createState(), XXH3_freeState);
  invariant(hash != nullptr, "XXH3 state allocated");
  XXH3_64bits_reset(hash.get());
  uint64_t size = 0;
  PayloadWriter p([&](const uint8_t* data, size_t n) {
    XXH3_64bits_update(hash.get(), data, n);
    size += n;
    compress(data, n, ZSTD_e_continue);
  });
  encode_livepoint_payload(lib, p);
  compress(nullptr, 0, ZSTD_e_end);
  put_le(head + 16, size, 8);
  put_le(head + 24, XXH3_64bits_digest(hash.get()), 8);
  invariant(out.patch(16, head + 16, 16), "a library written to a temporary file can take its header last");
  out.commit();
}

LivePoints read_livepoints(const std::string& path) {
  test_hook_internal_error("livepoint-read");  // tests/test_study.cpp
  FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) throw UserError(path + ": " + std::strerror(errno));
  std::unique_ptr<FILE, int (*)(FILE*)> guard(f, std::fclose);
  uint8_t head[kFileHeaderBytes];
  if (std::fread(head, 1, sizeof head, f) != sizeof head || std::memcmp(head, kMagic, 8) != 0)
    throw UserError(path + ": not a live-point library (no ROPSIMLP header; build one with `ropsim livepoints`)");
  const uint32_t version = uint32_t(get_le(head + 8, 4));
  if (version != kLivePointFileVersion)
    throw UserError(path + ": live-point library version " + std::to_string(version) + ", this ropsim reads " +
                    std::to_string(kLivePointFileVersion) + " (rebuild it with `ropsim livepoints`)");
  if (const uint32_t reserved = uint32_t(get_le(head + 12, 4)))
    throw UserError(path + ": not a valid live-point library (the reserved header field, bytes 12..15, is " +
                    std::to_string(reserved) + ", not 0)");
  const uint64_t size = get_le(head + 16, 8), sum = get_le(head + 24, 8);
  if (size > kMaxLivePointCount)
    throw UserError(path + ": not a valid live-point library (a payload of " + std::to_string(size) + " bytes)");
  // The payload grows as it is decompressed -- never beyond the size the
  // header declares, and never allocated on the header's word alone -- and is
  // charged to the budget as it grows, with as much again for what it decodes
  // into.
  BudgetShare mem;
  std::vector<uint8_t> payload;
  std::unique_ptr<ZSTD_DCtx, decltype(&ZSTD_freeDCtx)> dctx(ZSTD_createDCtx(), ZSTD_freeDCtx);
  invariant(dctx != nullptr, "zstd context allocated");
  std::vector<uint8_t> ibuf(ZSTD_DStreamInSize()), obuf(size_t(1) << 20);
  uint64_t charged = 0;
  size_t last = 1;
  for (;;) {
    const size_t n = std::fread(ibuf.data(), 1, ibuf.size(), f);
    if (n == 0) break;
    ZSTD_inBuffer ib{ibuf.data(), n, 0};
    while (ib.pos < ib.size) {
      if (last == 0) throw UserError(path + ": not a valid live-point library (bytes after the payload)");
      ZSTD_outBuffer ob{obuf.data(), obuf.size(), 0};
      last = ZSTD_decompressStream(dctx.get(), &ob, &ib);
      if (ZSTD_isError(last))
        throw UserError(path + ": not a valid live-point library (corrupt compressed data: " + ZSTD_getErrorName(last) +
                        ")");
      if (payload.size() + ob.pos > size)
        throw UserError(path + ": not a valid live-point library (the payload is longer than its header says)");
      if (payload.size() + ob.pos > charged) {
        const uint64_t more = std::max<uint64_t>(payload.size() + ob.pos - charged, uint64_t{16} << 20);
        mem.add(2 * more, path + ": the live-point library's payload");
        charged += more;
      }
      payload.insert(payload.end(), obuf.begin(), obuf.begin() + std::ptrdiff_t(ob.pos));
    }
  }
  if (std::ferror(f)) throw UserError(path + ": read error");
  if (last != 0 || payload.size() != size)
    throw UserError(path + ": not a valid live-point library (truncated: " + std::to_string(payload.size()) + " of " +
                    std::to_string(size) + " payload bytes)");
  if (XXH3_64bits(payload.data(), payload.size()) != sum)
    throw UserError(path + ": not a valid live-point library (the payload's checksum does not match)");
  return decode_livepoint_payload(payload, path);  // its points charged as they are decoded
}

void check_library_input(const LivePoints& lib, const std::string& lib_path, const InputSpec& in) {
  const InputIdentity id = input_identity(in);
  if (id.digest != lib.input.digest || id.from_trace != lib.input.from_trace)
    throw UserError(lib_path + ": the library was recorded from " + lib.input.description + " (digest " +
                    hex64(lib.input.digest) + "), not from " + id.description + " (digest " + hex64(id.digest) +
                    "); build one for it with `ropsim livepoints`");
}

void check_library_method(const LivePoints& lib, const std::string& lib_path, const MethodConfig& m) {
  const MethodConfig& l = lib.method;
  auto fail = [&](const std::string& what, const std::string& lib_v, const std::string& run_v) {
    throw UserError(lib_path + ": the library was recorded with " + what + " " + lib_v + ", the run asks for " + run_v +
                    " (a library serves one method and its numerics; build another with `ropsim livepoints`)");
  };
  if (l.method != m.method) fail("method", to_string(l.method), to_string(m.method));
  if (l.numerics.hash_bits != m.numerics.hash_bits)
    fail("numerics.hash_bits", std::to_string(l.numerics.hash_bits), std::to_string(m.numerics.hash_bits));
  if (l.numerics.alpha_bits != m.numerics.alpha_bits)
    fail("numerics.alpha_bits", std::to_string(l.numerics.alpha_bits), std::to_string(m.numerics.alpha_bits));
  if (l.numerics.surface_id_bits != m.numerics.surface_id_bits)
    fail("numerics.surface_id_bits", std::to_string(l.numerics.surface_id_bits),
         std::to_string(m.numerics.surface_id_bits));
  if (l.seed != m.seed) fail("seed", std::to_string(l.seed), std::to_string(m.seed));
  if (l.method == Method::kSlab && (l.slab_layers != m.slab_layers || l.slab_bits != m.slab_bits))
    fail("slab k/b", std::to_string(l.slab_layers) + "/" + std::to_string(l.slab_bits),
         std::to_string(m.slab_layers) + "/" + std::to_string(m.slab_bits));
  if (l.enderton_selection != m.enderton_selection)
    fail("enderton selection", l.enderton_selection == EndertonSelection::kOriginal ? "original" : "depth-first",
         m.enderton_selection == EndertonSelection::kOriginal ? "original" : "depth-first");
}

void check_library_sampling(const LivePoints& lib, const std::string& lib_path, const SamplingParams& p) {
  const SamplingParams& l = lib.params;
  // What a recording of this input places when p is asked for (a small input
  // is one whole unit): the library must hold that.
  const SamplingParams asked = p;
  const SamplingParams placed = placed_sampling(asked, lib.fragments);
  auto fail = [&](const char* what, const std::string& lib_v, const std::string& run_v) {
    throw UserError(lib_path + ": the library was recorded with " + what + " " + lib_v + ", the run asks for " + run_v +
                    " (a library serves one sampling; build another with `ropsim livepoints`)");
  };
  const std::pair<const char*, std::pair<uint64_t, uint64_t>> counts[] = {
      {"K (units)", {l.units, placed.units}},
      {"U (unit fragments)", {l.unit_fragments, placed.unit_fragments}},
      {"W (warm-up fragments)", {l.warmup_fragments, placed.warmup_fragments}},
      {"C (cool-down fragments)", {l.cooldown_fragments, placed.cooldown_fragments}},
      {"T (warming fragments)", {l.warming_fragments, placed.warming_fragments}},
  };
  for (const auto& [what, v] : counts)
    if (v.first != v.second) fail(what, std::to_string(v.first), std::to_string(v.second));
  if (l.warming_reach != placed.warming_reach) {
    char a[32], b[32];
    std::snprintf(a, sizeof a, "%g", l.warming_reach);
    std::snprintf(b, sizeof b, "%g", placed.warming_reach);
    fail("R (warming reach)", a, b);
  }
}

}  // namespace ropsim
