#include "tools/viewer/base64.h"

#include <gtest/gtest.h>

namespace anchormap::viewer {
namespace {

std::string Encode(const std::string& s) {
  return Base64Encode(reinterpret_cast<const uint8_t*>(s.data()), s.size());
}

TEST(Base64Test, EncodesTheRfc4648Vectors) {
  EXPECT_EQ(Encode(""), "");
  EXPECT_EQ(Encode("f"), "Zg==");
  EXPECT_EQ(Encode("fo"), "Zm8=");
  EXPECT_EQ(Encode("foo"), "Zm9v");
  EXPECT_EQ(Encode("foob"), "Zm9vYg==");
  EXPECT_EQ(Encode("fooba"), "Zm9vYmE=");
  EXPECT_EQ(Encode("foobar"), "Zm9vYmFy");
}

TEST(Base64Test, DecodeInvertsEncodeForEveryByteValueAndLength) {
  std::vector<uint8_t> bytes;
  for (int i = 0; i < 300; ++i) bytes.push_back(static_cast<uint8_t>((i * 37 + 11) % 256));
  for (size_t n = 0; n < bytes.size(); n += 7) {
    const auto decoded = Base64Decode(Base64Encode(bytes.data(), n));
    ASSERT_TRUE(decoded.has_value()) << n;
    EXPECT_EQ(*decoded, std::vector<uint8_t>(bytes.begin(), bytes.begin() + n)) << n;
  }
}

TEST(Base64Test, DecodeRefusesMalformedText) {
  EXPECT_FALSE(Base64Decode("Zm9").has_value());   // not a multiple of 4
  EXPECT_FALSE(Base64Decode("Zm=v").has_value());  // padding in the middle
  EXPECT_FALSE(Base64Decode("Zm9v YmFy").has_value());
  EXPECT_FALSE(Base64Decode("Z===").has_value());      // too much padding
  EXPECT_FALSE(Base64Decode("Zg==Zg==").has_value());  // padding before the end
  ASSERT_TRUE(Base64Decode("Zm9vYg==").has_value());
}

}  // namespace
}  // namespace anchormap::viewer
