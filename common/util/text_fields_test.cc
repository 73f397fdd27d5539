#include "common/util/text_fields.h"

#include <gtest/gtest.h>

namespace anchormap {
namespace {

TEST(SplitFieldsTest, SplitsAtWhitespaceRunsAndOptionallyCommas) {
  const auto fields = SplitFields("  ODOM 1.5\t-2 \r\n");
  ASSERT_EQ(fields.size(), 3u);
  EXPECT_EQ(fields[0], "ODOM");
  EXPECT_EQ(fields[1], "1.5");
  EXPECT_EQ(fields[2], "-2");
  EXPECT_EQ(SplitFields("1,2, 3").size(), 2u);  // "1,2," and "3"
  EXPECT_EQ(SplitFields("1,2, 3", true).size(), 3u);
  EXPECT_TRUE(SplitFields(" \t\n").empty());
}

TEST(ParseFiniteDoubleTest, AcceptsWholeFiniteNumbersOnly) {
  double v = 0.0;
  EXPECT_TRUE(ParseFiniteDouble("1.13486e+09", &v));
  EXPECT_DOUBLE_EQ(v, 1.13486e9);
  EXPECT_TRUE(ParseFiniteDouble("+0.25", &v));
  EXPECT_DOUBLE_EQ(v, 0.25);
  EXPECT_TRUE(ParseFiniteDouble("-0", &v));
  EXPECT_EQ(v, 0.0);
  v = 7.0;
  EXPECT_FALSE(ParseFiniteDouble("1.5x", &v));
  EXPECT_FALSE(ParseFiniteDouble("", &v));
  EXPECT_FALSE(ParseFiniteDouble("+", &v));
  EXPECT_FALSE(ParseFiniteDouble("nan", &v));
  EXPECT_FALSE(ParseFiniteDouble("-inf", &v));
  EXPECT_FALSE(ParseFiniteDouble("1e999", &v));  // out of range
  EXPECT_EQ(v, 7.0);                             // untouched on failure
}

TEST(ParseInt64Test, AcceptsWholeIntegersOnly) {
  int64_t v = 0;
  EXPECT_TRUE(ParseInt64("180", &v));
  EXPECT_EQ(v, 180);
  EXPECT_TRUE(ParseInt64("-3", &v));
  EXPECT_EQ(v, -3);
  EXPECT_FALSE(ParseInt64("180.0", &v));
  EXPECT_FALSE(ParseInt64("x", &v));
  EXPECT_FALSE(ParseInt64("99999999999999999999", &v));
  EXPECT_EQ(v, -3);
}

TEST(AbbreviateTest, CutsLongText) {
  EXPECT_EQ(Abbreviate("short"), "short");
  EXPECT_EQ(Abbreviate("abcdefgh", 3), "abc...");
  EXPECT_EQ(Abbreviate(std::string("1\0\x0b\xff", 4)), "1\\x00\\x0b\\xff");
}

TEST(ParseNumberFieldsTest, NamedFieldsInOrderOrWhichOneIsWrong) {
  const std::vector<const char*> names = {"t", "x", "y"};
  std::vector<double> v;
  ASSERT_TRUE(ParseNumberFields("1.5, -2 3e2", names, /*commas_separate=*/true, &v).ok());
  EXPECT_EQ(v, (std::vector<double>{1.5, -2.0, 300.0}));
  EXPECT_EQ(ParseNumberFields("1 2", names, false, &v).message(),
            "expected 3 fields (t x y), found 2");
  EXPECT_EQ(ParseNumberFields("1 nan 3", names, false, &v).message(),
            "field x 'nan' is not a finite number");
  EXPECT_FALSE(ParseNumberFields("1,2,3", names, /*commas_separate=*/false, &v).ok());
}

}  // namespace
}  // namespace anchormap
