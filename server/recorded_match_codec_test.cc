#include "server/recorded_match_codec.h"

#include <cstring>
#include <string>

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
  return {42,
          {PoseKey{TrajectoryId(3), 17}, PoseKey{TrajectoryId(1), 250}, MatchKind::kLoopRival},
          0xfedcba9876543210ULL,
          m};
}

bool SameBits(double a, double b) { return std::memcmp(&a, &b, sizeof(double)) == 0; }

TEST(RecordedMatchCodecTest, EveryFieldComesBackBitForBit) {
  const RecordedMatch in = FullMatch();
  const std::vector<uint8_t> bytes = EncodeRecordedMatch(in);
  const Result<RecordedMatch> out = DecodeRecordedMatch(bytes.data(), bytes.size());
  ASSERT_TRUE(out.ok()) << out.status().message();
  EXPECT_EQ(out->ordinal, 42);
  EXPECT_TRUE(out->tag == in.tag);
  EXPECT_EQ(out->tag.kind, MatchKind::kLoopRival);
  EXPECT_EQ(out->options_fingerprint, 0xfedcba9876543210ULL);
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
  for (const uint8_t v : {uint8_t{0}, uint8_t{3}, uint8_t{9}}) {
    std::vector<uint8_t> version = bytes;
    version[4] = v;
    EXPECT_NE(DecodeRecordedMatch(version.data(), version.size())
                  .status()
                  .message()
                  .find("version " + std::to_string(v) + ", this reads 1 to 2"),
              std::string::npos);
  }
  // The kind follows magic (4), version (4), ordinal (8) and two keys (12 each).
  for (const uint8_t kind : {uint8_t{0}, uint8_t{6}}) {
    std::vector<uint8_t> bad = bytes;
    bad[40] = kind;
    EXPECT_NE(DecodeRecordedMatch(bad.data(), bad.size()).status().message().find("bad kind"),
              std::string::npos);
  }
}

// A journal written before version 2 (no kind, no fingerprint) is still read: its results
// come back with kind kUnknown and fingerprint 0, which no server's options have, so a
// restart matches them again instead of reusing them (MatchPool).
TEST(RecordedMatchCodecTest, AVersionOneRecordIsReadWithoutKindOrFingerprint) {
  const RecordedMatch in = FullMatch();
  std::vector<uint8_t> old = EncodeRecordedMatch(in);
  ASSERT_EQ(old[40], static_cast<uint8_t>(MatchKind::kLoopRival));
  old.erase(old.begin() + 40, old.begin() + 40 + 1 + 8);  // the version 1 layout
  old[4] = 1;
  const Result<RecordedMatch> out = DecodeRecordedMatch(old.data(), old.size());
  ASSERT_TRUE(out.ok()) << out.status().message();
  EXPECT_EQ(out->ordinal, 42);
  EXPECT_TRUE(out->tag.query == in.tag.query);
  EXPECT_TRUE(out->tag.reference == in.tag.reference);
  EXPECT_EQ(out->tag.kind, MatchKind::kUnknown);
  EXPECT_EQ(out->options_fingerprint, 0u);
  ASSERT_TRUE(out->result.has_value());
  EXPECT_TRUE(SameBits(out->result->score, in.result->score));
  EXPECT_TRUE(SameBits(out->result->lattice.score, in.result->lattice.score));
  const std::vector<uint8_t> cut(old.begin(), old.end() - 1);
  EXPECT_FALSE(DecodeRecordedMatch(cut.data(), cut.size()).ok());
}

}  // namespace
}  // namespace anchormap
