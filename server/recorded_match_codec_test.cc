#include "server/recorded_match_codec.h"

#include <cstring>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

RecordedMatch FullMatch() {
  MatchResult m;
  m.pose = Pose2(1.0 / 3.0, -2.0 / 7.0, 3.0);
  m.score = 0.6180339887;
  m.overlap = 0.8712;
  for (int i = 0; i < 9; ++i) m.covariance(i / 3, i % 3) = 1e-4 * (i + 1) / 7.0;
  m.lattice_pose = Pose2(0.35, -0.3, 2.9);
  m.search.scored_nodes = 123456;
  m.search.leaves = 789;
  m.window.center = Pose2(0.1, 0.2, -0.3);
  m.window.angle_step_rad = 0.0123;
  m.window.half_angles = 12;
  m.window.half_cells_x = 40;
  m.window.half_cells_y = 41;
  m.lattice = {-3, 5, -7, 0.61};
  return {42, {PoseKey{TrajectoryId(3), 17}, PoseKey{TrajectoryId(1), 250}}, m};
}

bool SameBits(double a, double b) { return std::memcmp(&a, &b, sizeof(double)) == 0; }

TEST(RecordedMatchCodecTest, EveryFieldComesBackBitForBit) {
  const RecordedMatch in = FullMatch();
  const std::vector<uint8_t> bytes = EncodeRecordedMatch(in);
  const Result<RecordedMatch> out = DecodeRecordedMatch(bytes.data(), bytes.size());
  ASSERT_TRUE(out.ok()) << out.status().message();
  EXPECT_EQ(out->ordinal, 42);
  EXPECT_TRUE(out->tag == in.tag);
  ASSERT_TRUE(out->result.has_value());
  const MatchResult& a = *in.result;
  const MatchResult& b = *out->result;
  EXPECT_TRUE(SameBits(a.pose.x(), b.pose.x()));
  EXPECT_TRUE(SameBits(a.pose.y(), b.pose.y()));
  EXPECT_TRUE(SameBits(a.pose.theta(), b.pose.theta()));
  EXPECT_TRUE(SameBits(a.score, b.score));
  EXPECT_TRUE(SameBits(a.overlap, b.overlap));
  for (int i = 0; i < 9; ++i) {
    EXPECT_TRUE(SameBits(a.covariance(i / 3, i % 3), b.covariance(i / 3, i % 3)));
  }
  EXPECT_TRUE(SameBits(a.lattice_pose.theta(), b.lattice_pose.theta()));
  EXPECT_EQ(b.search.scored_nodes, 123456);
  EXPECT_EQ(b.search.leaves, 789);
  EXPECT_TRUE(SameBits(a.window.center.theta(), b.window.center.theta()));
  EXPECT_TRUE(SameBits(a.window.angle_step_rad, b.window.angle_step_rad));
  EXPECT_EQ(b.window.half_angles, 12);
  EXPECT_EQ(b.window.half_cells_x, 40);
  EXPECT_EQ(b.window.half_cells_y, 41);
  EXPECT_EQ(b.lattice.k, -3);
  EXPECT_EQ(b.lattice.dx, 5);
  EXPECT_EQ(b.lattice.dy, -7);
  EXPECT_TRUE(SameBits(a.lattice.score, b.lattice.score));

  RecordedMatch none = in;
  none.result.reset();
  const std::vector<uint8_t> none_bytes = EncodeRecordedMatch(none);
  const Result<RecordedMatch> none_out = DecodeRecordedMatch(none_bytes.data(), none_bytes.size());
  ASSERT_TRUE(none_out.ok());
  EXPECT_FALSE(none_out->result.has_value());
}

TEST(RecordedMatchCodecTest, DamagedBytesAreRefusedWithTheReason) {
  const std::vector<uint8_t> bytes = EncodeRecordedMatch(FullMatch());
  for (const size_t size : {size_t{0}, size_t{3}, size_t{20}, bytes.size() - 1}) {
    const Result<RecordedMatch> cut = DecodeRecordedMatch(bytes.data(), size);
    ASSERT_FALSE(cut.ok()) << size;
    EXPECT_EQ(cut.status().code(), ErrorCode::kDecodeFailed);
  }
  std::vector<uint8_t> longer = bytes;
  longer.push_back(0);
  EXPECT_NE(DecodeRecordedMatch(longer.data(), longer.size()).status().message().find("left over"),
            std::string::npos);
  std::vector<uint8_t> magic = bytes;
  magic[0] = 'X';
  EXPECT_NE(DecodeRecordedMatch(magic.data(), magic.size()).status().message().find("magic"),
            std::string::npos);
  std::vector<uint8_t> version = bytes;
  version[4] = 9;
  EXPECT_NE(
      DecodeRecordedMatch(version.data(), version.size()).status().message().find("version 9"),
      std::string::npos);
}

}  // namespace
}  // namespace anchormap
