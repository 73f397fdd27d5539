#include "common/util/reject_counter.h"

#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

TEST(RejectCounterTest, CountsByReasonAndLogsOncePerReasonAndContext) {
  std::vector<std::string> lines;
  SetLogSink([&](LogLevel, const std::string& line) { lines.push_back(line); });
  RejectCounter counter;
  counter.Count(ErrorCode::kNotFinite, "R1_LASER", "range 3 is nan");
  counter.Count(ErrorCode::kNotFinite, "R1_LASER", "range 4 is nan");
  counter.Count(ErrorCode::kNotFinite, "R2_LASER", "range 1 is inf");
  counter.Count(ErrorCode::kDuplicateSequence, "ANCHORMAP_KEYFRAMES", "seq 4 again");
  SetLogSink(nullptr);

  EXPECT_EQ(counter.count(ErrorCode::kNotFinite), 3);
  EXPECT_EQ(counter.count(ErrorCode::kDuplicateSequence), 1);
  EXPECT_EQ(counter.count(ErrorCode::kDecodeFailed), 0);
  EXPECT_EQ(counter.total(), 4);
  ASSERT_EQ(lines.size(), 3u);  // (not_finite, R1), (not_finite, R2), (duplicate, keyframes)
  EXPECT_NE(lines[0].find("R1_LASER: not_finite: range 3 is nan"), std::string::npos) << lines[0];
  EXPECT_EQ(counter.Summary(), "not_finite=3 duplicate_sequence=1");
  const auto non_zero = counter.NonZero();
  ASSERT_EQ(non_zero.size(), 2u);
  EXPECT_EQ(non_zero[0].first, "not_finite");
  EXPECT_EQ(non_zero[0].second, 3);
}

TEST(RejectCounterTest, EmptySummarySaysNone) {
  RejectCounter counter;
  EXPECT_EQ(counter.Summary(), "none");
  EXPECT_EQ(counter.total(), 0);
}

TEST(RejectCounterTest, EveryReasonHasADistinctName) {
  std::set<std::string> names;
  for (int i = 0; i < static_cast<int>(ErrorCode::kNumCodes); ++i) {
    names.insert(ToString(static_cast<ErrorCode>(i)));
  }
  EXPECT_EQ(names.size(), static_cast<size_t>(ErrorCode::kNumCodes));
  EXPECT_EQ(names.count("unknown_reason"), 0u);
}

}  // namespace
}  // namespace anchormap
