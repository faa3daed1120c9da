// The image codec (util/codec): OpenImageIO is a module loaded on first use,
// so no ropsim binary links it and a run that writes no image, or PNG images
// only (libpng in the process, to OpenImageIO's bytes), never loads it;
// what it encodes decodes back; a missing module is a one-line error naming
// the file being written, with no partial output; and image comparison gives
// its closed-form figures.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include "sim/image/image_io.h"
#include "tests/study_test_util.h"
#include "util/codec/image_codec.h"
#include "util/codec/png_encode.h"

namespace {

using namespace ropsim_test;

TEST(ImageCodec, NoBinaryLinksOpenImageIO) {
  Scratch s("codec-ldd");
  for (const char* bin : {ROPSIM_BINARY, "/proc/self/exe"}) {
    const Ran r = shell(s.dir, std::string("ldd '") + bin + "'", 60);
    ASSERT_EQ(r.status, 0) << "ldd " << bin << " failed: " << r.err;
    EXPECT_EQ(r.out.find("OpenImageIO"), std::string::npos)
        << bin << " links OpenImageIO: every process start would load its ~260 libraries\n"
        << r.out;
  }
}

TEST(ImageCodec, ExrRoundTripsExactlyAndPngToItsCodeValues) {
  const int w = 5, h = 3;
  std::vector<float> rgb(size_t(w * h * 3));
  for (size_t i = 0; i < rgb.size(); ++i) rgb[i] = float(i) / 7.0f - 0.25f;  // negatives kept by EXR
  const auto exr = ropsim::encode_exr_rgb(rgb.data(), w, h, "a.exr");
  Scratch s("codec-rt");
  const auto put = [&](const char* name, const std::vector<unsigned char>& b) {
    std::ofstream(s.dir / name, std::ios::binary)
        .write(reinterpret_cast<const char*>(b.data()), std::streamsize(b.size()));
    return (s.dir / name).string();
  };
  const ropsim::DecodedImage e = ropsim::decode_image_file(put("a.exr", exr));
  ASSERT_EQ(e.width, w);
  ASSERT_EQ(e.height, h);
  ASSERT_EQ(e.channels, 3);
  EXPECT_EQ(e.px, rgb) << "EXR (binary32) does not round-trip bit for bit";
  EXPECT_EQ(ropsim::encode_exr_rgb(rgb.data(), w, h, "b.exr"), exr) << "the same pixels gave different bytes";

  std::vector<unsigned char> rgb8(size_t(w * h * 3));
  for (size_t i = 0; i < rgb8.size(); ++i) rgb8[i] = (unsigned char)(i * 17);
  const auto png = ropsim::encode_png_rgb8(rgb8.data(), w, h, "a.png");
  const ropsim::DecodedImage p = ropsim::decode_image_memory(png.data(), png.size(), "png", "memory");
  ASSERT_EQ(p.px.size(), rgb8.size());
  for (size_t i = 0; i < rgb8.size(); ++i)  // code value / 255, to float rounding
    ASSERT_NEAR(p.px[i], float(rgb8[i]) / 255.0f, 1e-6f) << "PNG value " << i;
}

TEST(ImageCodec, BadDataAndWrongExtensionsAreErrorsNamingTheFile) {
  const unsigned char junk[16] = {1, 2, 3};
  try {
    ropsim::decode_image_memory(junk, sizeof junk, "png", "embedded.png of scene.toml");
    FAIL() << "junk decoded";
  } catch (const ropsim::ImageCodecError& e) {
    EXPECT_EQ(std::string(e.what()).rfind("embedded.png of scene.toml: ", 0), 0u) << e.what();
  }
  const float px[3] = {0, 0, 0};
  EXPECT_THROW(ropsim::encode_exr_rgb(px, 1, 1, "x.png"), ropsim::ImageCodecError);
}

TEST(ImageCodec, AMissingModuleIsAOneLineErrorAndNoOutput) {
  Scratch s("codec-missing");
  const Ran r = shell(s.dir,
                      "env ROPSIM_OIIO_MODULE=/nonexistent/libropsim_oiio.so '" ROPSIM_BINARY
                      "' run --scene cloth --spp 4 --quiet --out out.exr --report r.json",
                      120);
  EXPECT_EQ(r.status, 1) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << "not one line:\n" << r.err;
  EXPECT_NE(r.err.find("out.exr"), std::string::npos) << "the error does not name the file: " << r.err;
  EXPECT_NE(r.err.find("/nonexistent/libropsim_oiio.so"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(s.dir / "out.exr")) << "a partial image was left";
}

// A PNG is written by libpng in the process: a run that writes PNG images
// only needs no module (so it never loads OpenImageIO's libraries).
TEST(ImageCodec, WritingAPngNeedsNoModule) {
  Scratch s("codec-png-only");
  const Ran r = shell(s.dir,
                      "env ROPSIM_OIIO_MODULE=/nonexistent/libropsim_oiio.so '" ROPSIM_BINARY
                      "' run --scene cloth --spp 4 --quiet --out out.png --report r.json",
                      120);
  EXPECT_EQ(r.status, 0) << "writing a PNG tried the module:\n" << r.err;
  EXPECT_TRUE(fs::exists(s.dir / "out.png"));
}

// The in-process PNG writer gives the bytes OpenImageIO's writer gives for the
// same pixels, over sizes from one pixel to several IDAT chunks and content
// from flat to noise (each of libpng's row filters wins somewhere), so an
// image's file and its digest do not depend on which wrote it.
TEST(ImageCodec, PngEncoderWritesOpenImageIOsBytes) {
  struct Case {
    int w, h;
    int kind;  // 0 flat, 1 gradients, 2 noise, 3 stripes and steps
  };
  const Case cases[] = {{1, 1, 0},     {1, 1, 2},     {3, 2, 1},     {7, 5, 2},   {64, 64, 1},
                        {257, 129, 3}, {200, 300, 2}, {256, 256, 1}, {31, 400, 3}};
  for (const Case& c : cases) {
    std::vector<unsigned char> px(size_t(c.w) * size_t(c.h) * 3);
    uint32_t state = 2463534242u + uint32_t(c.w * 131 + c.h);  // xorshift32, fixed seed per case
    for (int y = 0; y < c.h; ++y)
      for (int x = 0; x < c.w; ++x)
        for (int ch = 0; ch < 3; ++ch) {
          unsigned v = 0;
          if (c.kind == 0) v = 90;
          if (c.kind == 1) v = unsigned(x * (ch + 1) + y * (3 - ch));
          if (c.kind == 2) {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            v = state >> 24;
          }
          if (c.kind == 3) v = ((x / 4 + y / 3) % 2) * 200 + unsigned(ch * 20 + y % 7);
          px[(size_t(y) * size_t(c.w) + size_t(x)) * 3 + size_t(ch)] = (unsigned char)(v & 255);
        }
    const ropsim::RowSource rows = [&](int y, void* row) {
      std::memcpy(row, px.data() + size_t(y) * size_t(c.w) * 3, size_t(c.w) * 3);
    };
    const auto ours = ropsim::encode_png_libpng(c.w, c.h, rows, "a.png");
    const auto oiio = ropsim::encode_png_oiio(c.w, c.h, rows, "a.png");
    ASSERT_EQ(ours.size(), oiio.size()) << c.w << " x " << c.h << " kind " << c.kind << ": the sizes differ";
    EXPECT_TRUE(ours == oiio) << c.w << " x " << c.h << " kind " << c.kind << ": the bytes differ";
    EXPECT_TRUE(ropsim::encode_png_rows(c.w, c.h, rows, "b.png") == ours)
        << "encode_png_rows does not take the in-process writer";
  }
}

TEST(ImageCompare, ClosedFormFigures) {
  const ropsim::Image a = ropsim::Image::from_dense(2, 1, {0, 0, 0, 0, 0, 0});
  const ropsim::Image b = ropsim::Image::from_dense(2, 1, {0.1f, 0, 0, 0, 0, -0.2f});
  const ropsim::CompareResult c = ropsim::compare_images(b, a);
  const double d1 = double(0.1f), d2 = double(-0.2f);
  const double rms = std::sqrt((d1 * d1 + d2 * d2) / 6);
  EXPECT_DOUBLE_EQ(c.rmse_8bit, rms * 255);
  EXPECT_DOUBLE_EQ(c.psnr_db, 20 * std::log10(1 / rms));
  EXPECT_DOUBLE_EQ(c.max_error_8bit, 0.2 * 255 * (double(0.2f) / 0.2));
  EXPECT_DOUBLE_EQ(c.mean_error_8bit, (d1 - d2) / 6 * 255);
  EXPECT_DOUBLE_EQ(c.bias_8bit, (d1 + d2) / 6 * 255);
  EXPECT_TRUE(std::isinf(ropsim::compare_images(a, a).psnr_db)) << "identical images have infinite PSNR";
  EXPECT_THROW(ropsim::compare_images(a, ropsim::Image(1, 1)), ropsim::ImageError);
}

}  // namespace

namespace {

// A file's transfer: its named colour space first, then the pixel type; a
// named space that is neither linear nor sRGB is refused, naming the file.
TEST(ImageTransfer, NamedSpaceFirstThenPixelTypeElseRefused) {
  using ropsim::Transfer;
  EXPECT_EQ(ropsim::transfer_of("a.exr", "Linear", true), Transfer::kLinear);
  EXPECT_EQ(ropsim::transfer_of("a.png", "sRGB", false), Transfer::kSrgb);
  EXPECT_EQ(ropsim::transfer_of("a.tif", "", true), Transfer::kLinear) << "float pixels, no name: linear";
  EXPECT_EQ(ropsim::transfer_of("a.png", "", false), Transfer::kSrgb) << "integer code values, no name: sRGB";
  EXPECT_EQ(ropsim::transfer_of("a.png", "linear", false), Transfer::kLinear) << "a named space wins";
  try {
    ropsim::transfer_of("g.png", "GammaCorrected2.2", false);
    ADD_FAILURE() << "a gamma-2.2 image was accepted as sRGB or linear";
  } catch (const ropsim::ImageError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("g.png"), std::string::npos) << m;
    EXPECT_NE(m.find("GammaCorrected2.2"), std::string::npos) << m;
    EXPECT_EQ(m.find('\n'), std::string::npos) << "one line: " << m;
  }
  // srgb_to_linear inverts linear_to_srgb over [0, 1].
  for (int i = 0; i <= 1000; ++i) {
    const float v = float(i) / 1000.0f;
    EXPECT_NEAR(ropsim::srgb_to_linear(ropsim::linear_to_srgb(v)), v, 2e-6f) << v;
  }
}

}  // namespace
