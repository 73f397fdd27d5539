// The bot_core copies must be wire-compatible with libbot2: same LCM fingerprints. And
// anchormap.keyframe_v1_t must keep the fingerprint keyframe_t had before it carried
// encounters_relayed, so that journals written then are still read.
#include <cstdint>

#include <gtest/gtest.h>

#include "anchormap/keyframe_t.hpp"
#include "anchormap/keyframe_v1_t.hpp"
#include "bot_core/planar_lidar_t.hpp"
#include "bot_core/pose_t.hpp"

namespace {

TEST(LcmtypesFingerprintTest, BotCoreTypesMatchLibbot2) {
  // Fingerprints of libbot2's bot2-core/lcmtypes computed with lcm-gen 1.3.1.
  EXPECT_EQ(static_cast<uint64_t>(bot_core::pose_t::getHash()), 0x2e16efb052b0105eULL);
  EXPECT_EQ(static_cast<uint64_t>(bot_core::planar_lidar_t::getHash()), 0xe3d17423180b5e8dULL);
}

TEST(LcmtypesFingerprintTest, KeyframeV1IsTheLayoutBeforeTheRelayCount) {
  // anchormap.keyframe_t's fingerprint at main a32ed7a (lcm-gen 1.3.1), before encounters_relayed.
  constexpr uint64_t kKeyframeBeforeRelayCount = 0x77396c089bc903cdULL;
  EXPECT_EQ(static_cast<uint64_t>(anchormap::keyframe_v1_t::getHash()), kKeyframeBeforeRelayCount);
  EXPECT_NE(static_cast<uint64_t>(anchormap::keyframe_t::getHash()), kKeyframeBeforeRelayCount);
}

TEST(LcmtypesFingerprintTest, PlanarLidarRoundTrips) {
  bot_core::planar_lidar_t scan;
  scan.utime = 123456789;
  scan.nranges = 3;
  scan.ranges = {1.0f, 2.5f, 30.0f};
  scan.nintensities = 0;
  scan.rad0 = -1.5f;
  scan.radstep = 0.01f;
  std::vector<uint8_t> buffer(scan.getEncodedSize());
  ASSERT_EQ(scan.encode(buffer.data(), 0, buffer.size()), static_cast<int>(buffer.size()));
  bot_core::planar_lidar_t decoded;
  ASSERT_EQ(decoded.decode(buffer.data(), 0, buffer.size()), static_cast<int>(buffer.size()));
  EXPECT_EQ(decoded.ranges, scan.ranges);
  EXPECT_FLOAT_EQ(decoded.radstep, 0.01f);
}

}  // namespace
