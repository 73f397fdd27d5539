#include "common/bus/wire_check.h"

#include <functional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/bus/authenticator.h"
#include "common/bus/codec.h"
#include "common/bus/map_codec.h"

namespace anchormap {
namespace {

using Walker = std::function<Status(const void*, size_t)>;

struct Sample {
  std::string name;
  Walker walker;
  std::vector<uint8_t> bytes;
};

Keyframe MakeKeyframe() {
  Keyframe k;
  k.robot = "R1";
  k.trajectory_id = 5;
  k.seq = 2;
  k.utime = 1000;
  k.scan.rad0 = -1.0f;
  k.scan.radstep = 0.01f;
  k.scan.max_range = 20.0f;
  k.scan.ranges.assign(50, 2.0f);
  return k;
}

std::vector<Sample> Samples() {
  LaserScan scan;
  scan.utime = 10;
  scan.rad0 = -1.0f;
  scan.radstep = 0.01f;
  scan.ranges.assign(30, 1.0f);
  MergedMap map;
  map.trajectories.push_back(
      MergedTrajectory{"R1", 1, true, Pose2(1, 2, 0.3), {5, 6}, {Pose2(), Pose2(1, 0, 0)}});
  map.trajectories.push_back(MergedTrajectory{"R2", 2, false, Pose2(), {}, {}});
  map.encounters.push_back({"R1", 1, 0, "R2", 2, 0});
  AnchorCovariances anchors;
  anchors.anchors.push_back({"R1", 1, Pose2(1, 2, 3), Eigen::Matrix3d::Identity()});
  anchors.anchors.push_back({"R2", 2, Pose2(), Eigen::Matrix3d::Identity()});
  GridTile tile;
  tile.width = 4;
  tile.height = 3;
  tile.cells.assign(12, -1);
  ServerStatus status;
  status.rejections = {{"not_finite", 3}, {"replay", 1}};
  Result<KeyRing> keys = ParseKeyRing("k " + std::string(64, '0'));
  AuthenticatorOptions options;
  options.sender = "R1";
  Result<Authenticator> auth = Authenticator::Create(std::move(*keys), options);
  const std::vector<uint8_t> payload = EncodeKeyframe(MakeKeyframe());
  return {
      {"pose", CheckPoseWire, EncodeOdometry({1, Pose2(1, 2, 3)})},
      {"planar_lidar", CheckPlanarLidarWire, EncodeLaser(scan)},
      {"keyframe", CheckKeyframeWire, EncodeKeyframe(MakeKeyframe())},
      {"encounter", CheckEncounterWire,
       EncodeEncounter(Encounter{1, "R1", 0, "R2", Pose2(), Eigen::Matrix3d::Identity()})},
      {"merged_map", CheckMergedMapWire, EncodeMergedMap(map)},
      {"anchor_covariances", CheckAnchorCovariancesWire, EncodeAnchorCovariances(anchors)},
      {"grid_tile", CheckGridTileWire, EncodeGridTile(tile)},
      {"server_status", CheckServerStatusWire, EncodeServerStatus(status)},
      {"signed", CheckSignedWire, auth->Seal("C", payload.data(), payload.size())},
  };
}

void PatchInt32(std::vector<uint8_t>* bytes, size_t offset, int32_t value) {
  const auto v = static_cast<uint32_t>(value);
  for (int i = 0; i < 4; ++i) (*bytes)[offset + i] = static_cast<uint8_t>(v >> (24 - 8 * i));
}

TEST(WireCheckTest, EveryWalkerAcceptsItsTypeAndRefusesEveryTruncation) {
  for (const Sample& s : Samples()) {
    EXPECT_TRUE(s.walker(s.bytes.data(), s.bytes.size()).ok()) << s.name;
    for (size_t n = 0; n < s.bytes.size(); ++n) {
      const Status status = s.walker(s.bytes.data(), n);
      EXPECT_FALSE(status.ok()) << s.name << " truncated to " << n;
      EXPECT_TRUE(status.code() == ErrorCode::kDecodeFailed ||
                  status.code() == ErrorCode::kAbsurdSize)
          << s.name << ": " << status.ToString();
    }
    EXPECT_FALSE(s.walker(nullptr, s.bytes.size()).ok()) << s.name;
  }
}

TEST(WireCheckTest, EveryWalkerRefusesEveryOtherFingerprint) {
  const std::vector<Sample> samples = Samples();
  for (const Sample& walker : samples) {
    for (const Sample& message : samples) {
      if (walker.name == message.name) continue;
      const Status status = walker.walker(message.bytes.data(), message.bytes.size());
      EXPECT_EQ(status.code(), ErrorCode::kDecodeFailed) << walker.name << " on " << message.name;
      EXPECT_NE(status.message().find("fingerprint"), std::string::npos) << status.message();
    }
  }
}

TEST(WireCheckTest, RefusesOversizeAndNegativeCounts) {
  // keyframe: fingerprint 8, utime 8, robot (4 + 3), trajectory 8, seq 4, encounters_relayed
  // 4, doubles 8 * 18, floats 4 * 3, then nranges.
  const size_t nranges = 8 + 8 + 7 + 8 + 4 + 4 + 8 * 18 + 12;
  std::vector<uint8_t> bytes = EncodeKeyframe(MakeKeyframe());
  for (int32_t bad : {CodecLimits::kMaxRanges + 1, -1, INT32_MAX, INT32_MIN}) {
    std::vector<uint8_t> b = bytes;
    PatchInt32(&b, nranges, bad);
    EXPECT_EQ(CheckKeyframeWire(b.data(), b.size()).code(), ErrorCode::kAbsurdSize) << bad;
  }
  PatchInt32(&bytes, nranges, 51);  // one more than the bytes hold
  EXPECT_EQ(CheckKeyframeWire(bytes.data(), bytes.size()).code(), ErrorCode::kDecodeFailed);
  // grid tile: 8 + 8 + 8 + 8 + 4 + 4, then width and height.
  GridTile tile;
  tile.width = tile.height = 2;
  tile.cells.assign(4, 0);
  std::vector<uint8_t> t = EncodeGridTile(tile);
  PatchInt32(&t, 40, 4097);
  EXPECT_EQ(CheckGridTileWire(t.data(), t.size()).code(), ErrorCode::kAbsurdSize);
  t = EncodeGridTile(tile);
  PatchInt32(&t, 44, 4096);  // 2 x 4096 cells in a 4-cell message
  EXPECT_EQ(CheckGridTileWire(t.data(), t.size()).code(), ErrorCode::kDecodeFailed);
}

TEST(WireCheckTest, RefusesBadStringLengthsAndMissingTerminators) {
  const std::vector<uint8_t> good = EncodeKeyframe(MakeKeyframe());  // robot length at 16
  for (int32_t bad : {0, -1, INT32_MIN}) {
    std::vector<uint8_t> b = good;
    PatchInt32(&b, 16, bad);
    EXPECT_EQ(CheckKeyframeWire(b.data(), b.size()).code(), ErrorCode::kDecodeFailed) << bad;
  }
  for (int32_t bad : {66, INT32_MAX}) {
    std::vector<uint8_t> b = good;
    PatchInt32(&b, 16, bad);
    EXPECT_EQ(CheckKeyframeWire(b.data(), b.size()).code(), ErrorCode::kAbsurdSize) << bad;
  }
  std::vector<uint8_t> b = good;
  PatchInt32(&b, 16, 2);  // "R" without its NUL: the next byte ('1') ends the string
  const Status unterminated = CheckKeyframeWire(b.data(), b.size());
  EXPECT_EQ(unterminated.code(), ErrorCode::kDecodeFailed);
  EXPECT_NE(unterminated.message().find("NUL"), std::string::npos) << unterminated.message();
  b = good;
  b[22] = '!';  // the terminator itself
  EXPECT_NE(CheckKeyframeWire(b.data(), b.size()).message().find("NUL"), std::string::npos);
  b = good;
  b[20] = 0;  // "\01": a NUL inside
  EXPECT_NE(CheckKeyframeWire(b.data(), b.size()).message().find("NUL inside"), std::string::npos);
  WireCursor cursor(good.data(), 17);  // a length field cut in the middle
  ASSERT_TRUE(cursor.Skip(16));
  EXPECT_FALSE(cursor.SkipString("robot", 64).ok());
}

}  // namespace
}  // namespace anchormap
