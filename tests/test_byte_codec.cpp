// The one little-endian encoding (util/byte_codec.h): fields, words and
// length-prefixed strings round-trip, the byte order is fixed whatever the
// host's, and reading past the end is a broken invariant.
#include <gtest/gtest.h>

#include <cstring>
#include <string>

#include "util/byte_codec.h"
#include "util/errors.h"

namespace ropsim {
namespace {

TEST(ByteCodec, FieldsAreLittleEndianWhateverTheHost) {
  uint8_t b[8] = {};
  put_le(b, 0x0102030405ull, 5);
  const uint8_t want[8] = {0x05, 0x04, 0x03, 0x02, 0x01, 0, 0, 0};
  EXPECT_EQ(std::memcmp(b, want, 8), 0) << "not least significant byte first";
  EXPECT_EQ(get_le(b, 5), 0x0102030405ull);
  EXPECT_EQ(get_le(b, 2), 0x0405u) << "a narrower read takes the low bytes";
  put_u48(b, 0xfedcba987654ull);
  EXPECT_EQ(get_u48(b), 0xfedcba987654ull);
  EXPECT_EQ(get_u16(b), 0x7654u);
  put_f32(b, -1.5f);
  EXPECT_EQ(get_u32(b), 0xbfc00000u) << "a float is written as its IEEE-754 bits";
  EXPECT_EQ(get_f32(b), -1.5f);
}

TEST(ByteCodec, WordsAndStringsRoundTrip) {
  std::string m;
  ByteWriter w(m);
  w.u64(~0ull);
  w.str("");
  w.str(std::string("a\0b", 3));
  w.u64(7);
  EXPECT_EQ(m.size(), 8u + 8u + 8u + 3u + 8u);
  ByteReader r(m, "the message holds its words");
  EXPECT_EQ(r.u64(), ~0ull);
  EXPECT_EQ(r.str(), "");
  EXPECT_EQ(r.str(), std::string("a\0b", 3));
  EXPECT_FALSE(r.done());
  EXPECT_EQ(r.u64(), 7u);
  EXPECT_TRUE(r.done());
}

TEST(ByteCodec, ReadingPastTheEndIsABrokenInvariant) {
  std::string m;
  ByteWriter(m).str("four");
  const std::string cut = m.substr(0, m.size() - 1);  // the string's last byte missing
  ByteReader r(cut, "the message holds its string");
  EXPECT_THROW(r.str(), InternalError) << "a string longer than what is left was read";
  const std::string seven(7, '\0');
  ByteReader r2(seven, "the message holds a word");
  EXPECT_THROW(r2.u64(), InternalError) << "a word was read from 7 bytes";
}

}  // namespace
}  // namespace ropsim
