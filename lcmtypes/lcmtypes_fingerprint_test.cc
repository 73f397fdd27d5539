// The bot_core copies must be wire-compatible with libbot2: same LCM fingerprints.
#include <cstdint>

#include <gtest/gtest.h>

#include "bot_core/planar_lidar_t.hpp"
#include "bot_core/pose_t.hpp"

namespace {

TEST(LcmtypesFingerprintTest, BotCoreTypesMatchLibbot2) {
  // Fingerprints of libbot2's bot2-core/lcmtypes computed with lcm-gen 1.3.1.
  EXPECT_EQ(static_cast<uint64_t>(bot_core::pose_t::getHash()), 0x2e16efb052b0105eULL);
  EXPECT_EQ(static_cast<uint64_t>(bot_core::planar_lidar_t::getHash()), 0xe3d17423180b5e8dULL);
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
