// The comparisons the tests use to name a difference (tests/compare_util.h):
// equal inputs give "", and unequal ones the first place they differ with
// both values.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "rtl_models/functional/image.h"
#include "tests/compare_util.h"
#include "traces/format/draw_state.h"

namespace {

using ropsim_test::first_byte_difference;
using ropsim_test::first_draw_table_difference;
using ropsim_test::first_element_difference;
using ropsim_test::first_image_difference;

TEST(CompareUtil, ImagesNameThePixelAndChannel) {
  ropsim::Image a(16, 9), b(16, 9);
  a.at(3, 2)[1] = 0.5f;
  EXPECT_EQ(first_image_difference(a, a), "");
  b.at(3, 2)[1] = 0.5f;
  EXPECT_EQ(first_image_difference(a, b), "");
  b.at(3, 2)[1] = 0.25f;
  b.at(12, 7)[0] = 1.0f;
  EXPECT_EQ(first_image_difference(a, b), "pixel (3, 2) channel g: 0.5 (0x3f000000) vs 0.25 (0x3e800000)");
  EXPECT_EQ(first_image_difference(a, ropsim::Image(16, 8)), "sizes 16 x 9 vs 16 x 8");
  b = a;
  b.at(0, 0)[2] = -0.0f;  // equal as floats, not as bits: operator== compares bits
  EXPECT_FALSE(a == b);
  EXPECT_EQ(first_image_difference(a, b), "pixel (0, 0) channel b: 0 (0x00000000) vs -0 (0x80000000)");
}

TEST(CompareUtil, BytesNameTheIndexAndBothBytes) {
  EXPECT_EQ(first_byte_difference("abc", "abc"), "");
  EXPECT_EQ(first_byte_difference("abc", "abd"), "byte 2: 0x63 vs 0x64 (sizes 3 and 3)");
  EXPECT_EQ(first_byte_difference("abc", "ab"), "sizes 3 vs 2 (the first 2 bytes equal)");
}

TEST(CompareUtil, SequencesCompareFloatsBitForBit) {
  const std::vector<float> a = {1.0f, 0.0f}, b = {1.0f, -0.0f};
  EXPECT_EQ(first_element_difference(a, a), "");
  EXPECT_EQ(first_element_difference(a, b), "element 1: 0 (0x00000000) vs -0 (0x80000000) (sizes 2 and 2)");
  const uint64_t x[3] = {1, 2, 3}, y[3] = {1, 2, 4};
  EXPECT_EQ(first_element_difference(x, y), "element 2: 3 vs 4 (sizes 3 and 3)");
  EXPECT_EQ(first_element_difference(std::vector<uint8_t>{1, 2}, std::vector<uint8_t>{1}),
            "sizes 2 vs 1 (the first 1 elements equal)");
}

TEST(CompareUtil, DrawTablesAndFieldsNameTheField) {
  std::vector<ropsim::DrawState> s = {ropsim::default_draw_state(1), ropsim::default_draw_state(2)};
  const ropsim::DrawTable a(s);
  s[1].color_mask = 0x7;
  EXPECT_EQ(first_draw_table_difference(a, a), "");
  EXPECT_EQ(first_draw_table_difference(a, ropsim::DrawTable(s)), "draw state 1 (draw 2): color_mask: 15 vs 7");
  EXPECT_EQ(ropsim_test::Fields().eq("x", 1, 1).eq("y", 2, 3).eq("z", 4, 5).str(), "y: 2 vs 3");
  EXPECT_EQ(ropsim_test::Fields().bits("z0", 0.0f, -0.0f).str(), "z0 (bits): 0 (0x00000000) vs -0 (0x80000000)");
}

}  // namespace
