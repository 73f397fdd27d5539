#include "tools/render/server_output.h"

#include <cmath>
#include <filesystem>

#include <gtest/gtest.h>

#include "tests/testing/scratch.h"
#include "tools/render/testing_helpers.h"

namespace anchormap::render {
namespace {

using ::anchormap::testing::ScratchPath;

TEST(ServerOutputTest, ReadsTheLastMapTheLastGridAndAllCovariances) {
  const std::string path = ScratchPath("server_output.lcmlog");
  ASSERT_TRUE(testing::WriteTestServerLog(path).ok());
  ServerOutput output;
  ASSERT_TRUE(ReadServerOutput(path, ChannelNames{}, &output).ok());
  ASSERT_TRUE(output.map);
  EXPECT_EQ(output.map->update, 9);
  EXPECT_EQ(output.merged_maps, 2);
  ASSERT_EQ(output.map->trajectories.size(), 3u);
  EXPECT_EQ(output.map->trajectories[0].key.robot, "R1");
  EXPECT_EQ(output.map->trajectories[0].key.trajectory_id, 11);
  EXPECT_FALSE(output.map->trajectories[2].anchored);
  EXPECT_EQ(output.map->NumPoses(), 8u);
  const Pose2* end = output.map->FindPose({"R1", 11}, 2);
  ASSERT_NE(end, nullptr);
  EXPECT_EQ(end->x(), 8.0);
  EXPECT_EQ(output.map->FindPose({"R1", 11}, 3), nullptr);
  EXPECT_EQ(output.map->FindPose({"R1", 99}, 0), nullptr);
  EXPECT_EQ(output.map->FindPose({"R2", 11}, 0), nullptr);  // the id is R1's, not R2's
  EXPECT_EQ(output.dangling_links, 0);
  // The grid: the four tiles of update 9, not the single tile of update 4.
  ASSERT_EQ(output.grid.size(), 4u);
  for (const GridTile& tile : output.grid) EXPECT_EQ(tile.update, 9);
  EXPECT_EQ(output.grid_tile_messages, 5);
  // Covariances: 9 messages of 2 anchors; R2's sigma_xy goes 2.0 -> 0.4.
  EXPECT_EQ(output.covariance_messages, 9);
  ASSERT_EQ(output.anchor_samples.size(), 18u);
  EXPECT_EQ(output.anchor_samples[1].key.robot, "R2");
  EXPECT_NEAR(output.anchor_samples[1].sigma_xy_m, 2.0, 1e-12);
  EXPECT_NEAR(output.anchor_samples[17].sigma_xy_m, 0.4, 1e-12);
  EXPECT_NEAR(output.anchor_samples[0].sigma_xy_m, std::sqrt(2e-6), 1e-12);
  EXPECT_EQ(output.undecodable, 0);
  ASSERT_TRUE(output.status);
  EXPECT_EQ(output.status->keyframes, 8);
  EXPECT_EQ(output.status->num_anchored, 2);
  ASSERT_EQ(output.status->rejections.size(), 1u);
  EXPECT_EQ(output.status->rejections[0].first, "duplicate_seq");
  EXPECT_EQ(output.status->rejections[0].second, 2);
}

// anchormap-render --key-file: a signed log reads as the plain one; messages outside an
// envelope (forged) or under another key are refused and counted.
TEST(ServerOutputTest, WithAKeyOnlyTheServersSignedOutputsAreRead) {
  const std::string key = "fleet " + std::string(64, 'b');
  Authenticator server = *Authenticator::Create(*ParseKeyRing(key), {"", "server"});
  Authenticator checking = *Authenticator::Create(*ParseKeyRing(key), {"", "render"});
  const std::string path = ScratchPath("server_output_signed.lcmlog");
  ASSERT_TRUE(testing::WriteTestServerLog(path, &server).ok());
  ServerOutput output;
  ASSERT_TRUE(ReadServerOutput(path, ChannelNames{}, &output, &checking).ok());
  ASSERT_TRUE(output.map);
  EXPECT_EQ(output.map->update, 9);
  EXPECT_EQ(output.merged_maps, 2);
  EXPECT_EQ(output.unauthenticated, 0);
  EXPECT_EQ(output.undecodable, 0);
  EXPECT_EQ(output.grid.size(), 4u);
  EXPECT_EQ(output.anchor_samples.size(), 18u);
  ASSERT_TRUE(output.status);
  EXPECT_EQ(output.status->keyframes, 8);
  // Another fleet's key: all 17 messages refused, nothing read.
  Authenticator stranger =
      *Authenticator::Create(*ParseKeyRing("other " + std::string(64, 'c')), {"", "render"});
  ServerOutput refused;
  ASSERT_TRUE(ReadServerOutput(path, ChannelNames{}, &refused, &stranger).ok());
  EXPECT_FALSE(refused.map);
  EXPECT_EQ(refused.unauthenticated, 17);  // 2 maps, 5 tiles, 9 covariances, 1 status
  // An unsigned (forged) map after a signed one: the signed one is the map.
  const std::string mixed = ScratchPath("server_output_forged.lcmlog");
  {
    LcmLogWriter writer;
    ASSERT_TRUE(writer.Open(mixed).ok());
    const anchormap::merged_map_t map = testing::TestMergedMap(4);
    std::vector<uint8_t> bytes(static_cast<size_t>(map.getEncodedSize()));
    map.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
    const std::vector<uint8_t> sealed =
        server.Seal("ANCHORMAP_MERGED_MAP", bytes.data(), bytes.size());
    ASSERT_TRUE(writer.WriteRaw("ANCHORMAP_MERGED_MAP", 1, sealed.data(), sealed.size()).ok());
    ASSERT_TRUE(writer.Write("ANCHORMAP_MERGED_MAP", 2, testing::TestMergedMap(10)).ok());
  }
  ServerOutput forged;
  ASSERT_TRUE(ReadServerOutput(mixed, ChannelNames{}, &forged, &checking).ok());
  ASSERT_TRUE(forged.map);
  EXPECT_EQ(forged.map->update, 4);
  EXPECT_EQ(forged.unauthenticated, 1);
  // Without the key the envelope does not decode as a map: the forged one is read.
  ServerOutput keyless;
  ASSERT_TRUE(ReadServerOutput(mixed, ChannelNames{}, &keyless).ok());
  ASSERT_TRUE(keyless.map);
  EXPECT_EQ(keyless.map->update, 10);
  EXPECT_EQ(keyless.undecodable, 1);
}

TEST(ServerOutputTest, BadMessagesAreCountedNotFatal) {
  const std::string path = ScratchPath("server_output_bad.lcmlog");
  {
    LcmLogWriter writer;
    ASSERT_TRUE(writer.Open(path).ok());
    const uint8_t garbage[5] = {1, 2, 3, 4, 5};
    EXPECT_TRUE(writer.WriteRaw("ANCHORMAP_MERGED_MAP", 1, garbage, sizeof(garbage)).ok());
    EXPECT_TRUE(writer.WriteRaw("ANCHORMAP_GRID_TILES", 2, garbage, sizeof(garbage)).ok());
    EXPECT_TRUE(writer.Write("ANCHORMAP_MERGED_MAP", 3, testing::TestMergedMap(2)).ok());
    anchormap::merged_map_t broken = testing::TestMergedMap(3);  // poses with NaN
    broken.trajectories[0].poses[1][0] = std::nan("");
    EXPECT_TRUE(writer.Write("ANCHORMAP_MERGED_MAP", 4, broken).ok());
    anchormap::grid_tile_t wrong = testing::TestTile(1, 0, 0);
    wrong.resolution = 0.0;
    EXPECT_TRUE(writer.Write("ANCHORMAP_GRID_TILES", 5, wrong).ok());
    // A tile whose height field says -1: lcm-gen's decoder would resize a vector to
    // 2^64 - 1 elements and throw; the reader must count it, not crash.
    const anchormap::grid_tile_t tile = testing::TestTile(1, 0, 0);
    std::vector<uint8_t> bytes(tile.getEncodedSize());
    tile.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
    for (int i = 44; i < 48; ++i)
      bytes[i] = 0xff;  // hash 8, utime 8, update 8, resolution 8,
                        // tile_x 4, tile_y 4, width 4, then height
    EXPECT_TRUE(writer.WriteRaw("ANCHORMAP_GRID_TILES", 6, bytes.data(), bytes.size()).ok());
    EXPECT_TRUE(writer.WriteRaw("OTHER_CHANNEL", 6, garbage, sizeof(garbage)).ok());
  }
  ServerOutput output;
  ASSERT_TRUE(ReadServerOutput(path, ChannelNames{}, &output).ok());
  EXPECT_EQ(output.undecodable, 5);
  ASSERT_TRUE(output.map);
  EXPECT_EQ(output.map->update, 2);  // the last VALID map
  EXPECT_TRUE(output.grid.empty());
}

TEST(ServerOutputTest, TilesMissingFromTheLastUpdateComeFromRecentOnes) {
  const std::string path = ScratchPath("server_output_cut.lcmlog");
  {
    LcmLogWriter writer;
    ASSERT_TRUE(writer.Open(path).ok());
    // Update 4 has a tile (9, 9) that no later update has.
    EXPECT_TRUE(writer.Write("ANCHORMAP_GRID_TILES", 1, testing::TestTile(4, 9, 9)).ok());
    for (int tx = 0; tx < 3; ++tx)
      EXPECT_TRUE(writer.Write("ANCHORMAP_GRID_TILES", 2, testing::TestTile(5, tx, 0)).ok());
    EXPECT_TRUE(writer.Write("ANCHORMAP_GRID_TILES", 3, testing::TestTile(6, 1, 0)).ok());
    // then stopped
  }
  ServerOutput output;
  ASSERT_TRUE(ReadServerOutput(path, ChannelNames{}, &output).ok());
  ASSERT_EQ(output.grid.size(), 4u);
  EXPECT_EQ(output.grid_update, 6);
  EXPECT_EQ(output.grid_tiles_from_earlier_updates, 3);
  // In tile order: (0, 0) from update 5, (1, 0) from update 6, (2, 0) from 5, (9, 9) from 4.
  EXPECT_EQ(output.grid[0].update, 5);
  EXPECT_EQ(output.grid[1].update, 6);
  EXPECT_EQ(output.grid[1].tile_x, 1);
  EXPECT_EQ(output.grid[3].tile_x, 9);
}

// The server sends only the tiles that changed: a tile of an old update is still current.
TEST(ServerOutputTest, TilesOfOldUpdatesAreKept) {
  const std::string path = ScratchPath("server_output_old.lcmlog");
  {
    LcmLogWriter writer;
    ASSERT_TRUE(writer.Open(path).ok());
    EXPECT_TRUE(writer.Write("ANCHORMAP_GRID_TILES", 1, testing::TestTile(1, 9, 9)).ok());
    for (int update = 2; update <= 7; ++update) {
      EXPECT_TRUE(
          writer.Write("ANCHORMAP_GRID_TILES", update, testing::TestTile(update, 0, 0)).ok());
    }
  }
  ServerOutput output;
  ASSERT_TRUE(ReadServerOutput(path, ChannelNames{}, &output).ok());
  ASSERT_EQ(output.grid.size(), 2u);
  EXPECT_EQ(output.grid[0].update, 7);  // (0, 0)
  EXPECT_EQ(output.grid[1].update, 1);  // (9, 9), 6 updates old
  EXPECT_EQ(output.grid_tiles_from_earlier_updates, 1);
}

TEST(ServerOutputTest, MissingFileIsAnError) {
  ServerOutput output;
  EXPECT_FALSE(ReadServerOutput(ScratchPath("absent.lcmlog"), ChannelNames{}, &output).ok());
}

}  // namespace
}  // namespace anchormap::render
