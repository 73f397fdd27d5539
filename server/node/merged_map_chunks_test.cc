// The merged map on the bus, end to end: MapChunker (server) -> codec -> MergedMapAssembler
// (every reader). The assembled map must be the server's map (poses within the chunker's
// tolerance), a map update must send only the chunks that changed (those that only moved
// within a budget, the farthest first, every chunk again within a bounded number of
// updates), and a lost chunk must leave the previous complete map in place until the full
// map repairs it.

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "common/bus/map_codec.h"
#include "common/bus/merged_map_assembler.h"
#include "common/geometry/angle.h"
#include "server/map_chunker.h"

namespace anchormap {
namespace {

// Two trajectories of 600 and 100 keyframes (chunks of 256: 3 + 1), one unanchored one,
// and encounters between them.
MergedMap TestMap() {
  MergedMap map;
  map.utime = 1'000'000;
  map.update = 1;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-50.0, 50.0);
  const std::vector<std::tuple<std::string, int64_t, int, bool>> trajectories = {
      {"R1", 11, 600, true}, {"R2", 12, 100, true}, {"R3", 13, 5, false}};
  for (const auto& [robot, id, poses, anchored] : trajectories) {
    MergedTrajectory t;
    t.robot = robot;
    t.trajectory_id = id;
    t.anchored = anchored;
    // One draw per statement: a call's argument order is unspecified (gcc's order kept).
    if (anchored) {
      const double theta = 0.01 * u(rng);
      const double y = u(rng);
      const double x = u(rng);
      t.T_global_local = Pose2(x, y, theta);
    }
    for (int i = 0; i < poses; ++i) {
      const double theta = 0.05 * u(rng);
      const double y = u(rng);
      const double x = u(rng);
      t.poses.emplace_back(x, y, theta);
      t.pose_utimes.push_back(1000 * i);
    }
    map.trajectories.push_back(t);
  }
  map.encounters = {{"R1", 11, 300, "R2", 12, 40, ConstraintKind::kDirectEncounter},
                    {"R2", 12, 99, "R1", 11, 599, ConstraintKind::kScanEncounter},
                    {"R1", 11, 10, "R1", 11, 500, ConstraintKind::kLoopClosure},
                    {"R1", 11, 2, "R2", 12, 3, ConstraintKind::kScanEncounter}};
  return map;
}

// Sends a split through the codec into `assembler`, chunks first, skipping chunk `lose`.
bool Deliver(const MapChunker::Split& split, MergedMapAssembler* assembler, int lose = -1) {
  bool completed = false;
  for (size_t i = 0; i < split.chunks.size(); ++i) {
    if (static_cast<int>(i) == lose) continue;
    const std::vector<uint8_t> bytes = EncodeMergedMapChunk(split.chunks[i]);
    EXPECT_TRUE(assembler->Accept(channels::kMapChunks, bytes.data(), bytes.size()).ok());
  }
  const std::vector<uint8_t> bytes = EncodeMergedMapHeader(split.header);
  EXPECT_TRUE(assembler->Accept(channels::kMapHeader, bytes.data(), bytes.size(), &completed).ok());
  return completed;
}

// The largest pose difference between two maps of the same shape (inf when they differ).
double MaxDifference(const MergedMap& a, const MergedMap& b) {
  if (a.trajectories.size() != b.trajectories.size() || a.update != b.update) return INFINITY;
  double worst = 0.0;
  for (size_t t = 0; t < a.trajectories.size(); ++t) {
    const MergedTrajectory &x = a.trajectories[t], &y = b.trajectories[t];
    if (x.robot != y.robot || x.trajectory_id != y.trajectory_id || x.anchored != y.anchored ||
        x.poses.size() != y.poses.size() || x.pose_utimes != y.pose_utimes) {
      return INFINITY;
    }
    for (size_t i = 0; i < x.poses.size(); ++i) {
      worst = std::max({worst, std::abs(x.poses[i].x() - y.poses[i].x()),
                        std::abs(x.poses[i].y() - y.poses[i].y()),
                        std::abs(AngleDifference(x.poses[i].theta(), y.poses[i].theta()))});
    }
  }
  if (a.encounters != b.encounters) return INFINITY;
  return worst;
}

TEST(MergedMapChunksTest, AssembledMapIsTheServersMap) {
  const MergedMap map = TestMap();
  MapChunker chunker;
  const MapChunker::Split split = chunker.Update(map, /*full=*/false);
  EXPECT_EQ(split.chunks.size(), 3u + 1u + 1u);
  size_t largest = 0;
  for (const MergedMapChunk& chunk : split.chunks) {
    largest = std::max(largest, EncodeMergedMapChunk(chunk).size());
  }
  EXPECT_LT(largest, 9000u);  // 256 poses x 32 bytes, plus names and links
  EXPECT_EQ(split.header.num_encounters, 4);
  MergedMapAssembler assembler;
  EXPECT_TRUE(Deliver(split, &assembler));
  ASSERT_TRUE(assembler.map());
  EXPECT_LT(MaxDifference(*assembler.map(), map), 1e-9);
  EXPECT_EQ(assembler.missing_chunks(), 0);
}

TEST(MergedMapChunksTest, AnUpdateSendsOnlyTheChunksThatChanged) {
  MergedMap map = TestMap();
  MapChunker chunker;
  MergedMapAssembler assembler;
  ASSERT_TRUE(Deliver(chunker.Update(map, false), &assembler));
  // Update 2: R1's pose 300 (chunk 1) moves 2 mm, every pose moves 0.5 mm (under the
  // tolerance), R2's anchor moves 1 m (its local poses do not), R3 gets a keyframe.
  map.update = 2;
  for (MergedTrajectory& t : map.trajectories) {
    for (Pose2& p : t.poses) p = Pose2(p.x() + 0.0005, p.y(), p.theta());
  }
  Pose2& moved = map.trajectories[0].poses[300];
  moved = Pose2(moved.x() + 0.002, moved.y(), moved.theta());
  MergedTrajectory& r2 = map.trajectories[1];
  const Pose2 shift(1.0, 0.0, 0.0);
  r2.T_global_local = Compose(shift, r2.T_global_local);
  for (Pose2& p : r2.poses) p = Compose(shift, p);
  map.trajectories[2].poses.emplace_back(1.0, 2.0, 0.3);
  map.trajectories[2].pose_utimes.push_back(9000);
  const MapChunker::Split split = chunker.Update(map, false);
  ASSERT_EQ(split.chunks.size(), 2u);
  EXPECT_EQ(split.chunks[0].robot, "R1");
  EXPECT_EQ(split.chunks[0].chunk_index, 1);
  EXPECT_EQ(split.chunks[1].robot, "R3");
  EXPECT_TRUE(Deliver(split, &assembler));
  ASSERT_TRUE(assembler.map());
  const double difference = MaxDifference(*assembler.map(), map);
  EXPECT_GT(difference, 1e-4);          // the 0.5 mm moves did not travel...
  EXPECT_LE(difference, 0.001 + 1e-9);  // ...and that is all that is missing
  // The full map brings every chunk at its current content.
  map.update = 3;
  const MapChunker::Split full = chunker.Update(map, /*full=*/true);
  EXPECT_EQ(full.chunks.size(), 5u);
  EXPECT_TRUE(Deliver(full, &assembler));
  EXPECT_LT(MaxDifference(*assembler.map(), map), 1e-9);
}

TEST(MergedMapChunksTest, ALostChunkKeepsThePreviousMapUntilTheFullMap) {
  MergedMap map = TestMap();
  MapChunker chunker;
  MergedMapAssembler assembler;
  ASSERT_TRUE(Deliver(chunker.Update(map, false), &assembler));
  map.update = 2;
  map.trajectories[0].poses.emplace_back(0.0, 0.0, 0.0);  // R1's chunk 2 changes
  map.trajectories[0].pose_utimes.push_back(700'000);
  EXPECT_FALSE(Deliver(chunker.Update(map, false), &assembler, /*lose=*/0));
  EXPECT_EQ(assembler.missing_chunks(), 1);
  ASSERT_TRUE(assembler.map());
  EXPECT_EQ(assembler.map()->update, 1);  // the previous complete map
  map.update = 3;
  EXPECT_FALSE(Deliver(chunker.Update(map, false), &assembler));  // nothing changed: still missing
  map.update = 4;
  EXPECT_TRUE(Deliver(chunker.Update(map, /*full=*/true), &assembler));
  EXPECT_LT(MaxDifference(*assembler.map(), map), 1e-9);
}

TEST(MergedMapChunksTest, ChunksAfterTheirHeaderAndOldSingleMessagesAssembleToo) {
  const MergedMap map = TestMap();
  const MapChunker::Split split = MapChunker().Update(map, false);
  MergedMapAssembler assembler;
  bool completed = false;
  std::vector<uint8_t> bytes = EncodeMergedMapHeader(split.header);
  ASSERT_TRUE(assembler.Accept(channels::kMapHeader, bytes.data(), bytes.size(), &completed).ok());
  EXPECT_FALSE(completed);
  EXPECT_EQ(assembler.missing_chunks(), 5);
  for (size_t i = 0; i < split.chunks.size(); ++i) {
    bytes = EncodeMergedMapChunk(split.chunks[i]);
    ASSERT_TRUE(
        assembler.Accept(channels::kMapChunks, bytes.data(), bytes.size(), &completed).ok());
    EXPECT_EQ(completed, i + 1 == split.chunks.size());
  }
  EXPECT_LT(MaxDifference(*assembler.map(), map), 1e-9);
  // A log of a server before the chunks: one merged_map_t.
  MergedMapAssembler old;
  bytes = EncodeMergedMap(map);
  ASSERT_TRUE(old.Accept(channels::kMergedMap, bytes.data(), bytes.size(), &completed).ok());
  EXPECT_TRUE(completed);
  EXPECT_LT(MaxDifference(*old.map(), map), 1e-12);
  // Garbage is refused and changes nothing.
  const uint8_t garbage[] = {1, 2, 3, 4, 5, 6, 7, 8, 9};
  EXPECT_FALSE(old.Accept(channels::kMapChunks, garbage, sizeof(garbage)).ok());
  EXPECT_FALSE(old.Accept(channels::kMapHeader, garbage, sizeof(garbage)).ok());
  EXPECT_EQ(old.map()->update, 1);
}

// Every pose of `map` moved by a correction: x by `step` times a factor that grows along
// each trajectory and differs per trajectory (the chunks move by different amounts), all in
// the global frame.
void Correct(MergedMap* map, double step) {
  for (size_t t = 0; t < map->trajectories.size(); ++t) {
    std::vector<Pose2>& poses = map->trajectories[t].poses;
    for (size_t i = 0; i < poses.size(); ++i) {
      const double shift = step * (1.0 + 0.3 * static_cast<double>(t) +
                                   static_cast<double>(i) / static_cast<double>(poses.size()));
      poses[i] = Pose2(poses[i].x() + shift, poses[i].y(), poses[i].theta());
    }
  }
}

// The chunk's keyframes in its trajectory: [first, end).
std::pair<size_t, size_t> Range(const MergedMapChunk& chunk, int32_t chunk_poses) {
  const size_t first = static_cast<size_t>(chunk.chunk_index) * static_cast<size_t>(chunk_poses);
  return {first, first + chunk.local_poses.size()};
}

TEST(MergedMapChunksTest, MovedChunksGoByABudgetFarthestFirstEachAgainWithinTheRefreshBound) {
  MergedMap map = TestMap();  // 600 + 100 + 5 poses: at 16 poses a chunk, 38 + 7 + 1 chunks
  MapChunkerOptions options;
  options.chunk_poses = 16;
  options.max_moved_chunks = 4;
  options.max_read_chunks = 0;  // every chunk's poses read at every update
  MapChunker chunker(options);
  MergedMapAssembler assembler;
  const MapChunker::Split first = chunker.Update(map, /*full=*/false, /*refresh=*/0.1);
  ASSERT_EQ(first.chunks.size(), 46u);  // everything is new
  ASSERT_TRUE(Deliver(first, &assembler));
  // Every update: a correction moves every chunk past the tolerance, and R3 gets a keyframe.
  std::map<std::tuple<std::string, int64_t, int32_t>, int64_t> last_sent;
  for (const MergedMapChunk& c : first.chunks)
    last_sent[{c.robot, c.trajectory_id, c.chunk_index}] = 1;
  int64_t moved_sent = 0;
  for (int64_t update = 2; update <= 40; ++update) {
    map.update = update;
    Correct(&map, 0.003);
    map.trajectories[2].poses.emplace_back(0.1 * static_cast<double>(update), 0.0, 0.0);
    map.trajectories[2].pose_utimes.push_back(1000 * update);
    const MapChunker::Split split = chunker.Update(map, false, 0.1);
    // R3's chunk (rewritten) + 4 moved + ceil(0.1 x 46) = 5 refreshed, at most.
    EXPECT_LE(split.chunks.size(), 1u + 4u + 5u) << update;
    int rewritten = 0;
    for (const MergedMapChunk& c : split.chunks) {
      last_sent[{c.robot, c.trajectory_id, c.chunk_index}] = update;
      if (c.robot == "R3" &&
          Range(c, options.chunk_poses).second == map.trajectories[2].poses.size()) {
        ++rewritten;  // the chunk with the new keyframe
      }
    }
    EXPECT_EQ(rewritten, 1);
    moved_sent += static_cast<int64_t>(split.chunks.size()) - 1;
    // Each chunk went out within the last 10 updates (1 / refresh).
    for (const auto& [id, when] : last_sent) EXPECT_GT(when, update - 10) << std::get<0>(id);
    ASSERT_TRUE(Deliver(split, &assembler)) << update;
    // The subscriber's map: every chunk at the bits it was last sent with.
    ASSERT_TRUE(assembler.map());
    EXPECT_EQ(assembler.map()->update, update);
  }
  EXPECT_EQ(moved_sent, 39 * (4 + 5));  // the budget and the refresh were used in full
  // The farthest moved first: after the correction of one chunk only, that chunk goes.
  map.update = 41;
  std::vector<Pose2>& r1 = map.trajectories[0].poses;
  r1[100] = Pose2(r1[100].x(), r1[100].y() + 0.05, r1[100].theta());
  const MapChunker::Split split = chunker.Update(map, false, 0.0);
  bool found = false;
  for (const MergedMapChunk& c : split.chunks) {
    const auto [begin, end] = Range(c, options.chunk_poses);
    found = found || (c.robot == "R1" && begin <= 100 && 100 < end);
  }
  EXPECT_TRUE(found);
  EXPECT_LE(split.chunks.size(), 4u);
}

TEST(MergedMapChunksTest, AnUpdateReadsTheLeastRecentlyReadChunksWithinItsBound) {
  MergedMap map = TestMap();  // 38 + 7 + 1 chunks of 16 poses
  MapChunkerOptions options;
  options.chunk_poses = 16;
  options.max_moved_chunks = 0;  // every chunk read and moved goes
  options.max_read_chunks = 8;
  MapChunker chunker(options);
  MergedMapAssembler assembler;
  ASSERT_TRUE(Deliver(chunker.Update(map, false), &assembler));
  // Everything moves at every update: only the chunks read can be seen to, 8 per update,
  // each chunk once per ceil(46 / 8) = 6 updates.
  std::map<std::tuple<std::string, int64_t, int32_t>, int> times_sent;
  for (int64_t update = 2; update <= 13; ++update) {
    map.update = update;
    Correct(&map, 0.003);
    const MapChunker::Split split = chunker.Update(map, false);
    EXPECT_EQ(split.chunks.size(), 8u) << update;
    for (const MergedMapChunk& c : split.chunks)
      ++times_sent[{c.robot, c.trajectory_id, c.chunk_index}];
    ASSERT_TRUE(Deliver(split, &assembler));
  }
  // 12 updates x 8 = 96 reads: every chunk twice, four of them a third time.
  ASSERT_EQ(times_sent.size(), 46u);
  for (const auto& [id, times] : times_sent) {
    EXPECT_GE(times, 2) << std::get<0>(id) << " " << std::get<2>(id);
    EXPECT_LE(times, 3) << std::get<0>(id) << " " << std::get<2>(id);
  }
  // Once the map stops moving, the subscriber's map is the server's within 6 updates; then
  // the chunks read (all unmoved) are not sent.
  for (int64_t update = 14; update <= 19; ++update) {
    map.update = update;
    ASSERT_TRUE(Deliver(chunker.Update(map, false), &assembler));
  }
  EXPECT_LT(MaxDifference(*assembler.map(), map), 1e-9);
  map.update = 20;
  EXPECT_TRUE(chunker.Update(map, false).chunks.empty());
}

TEST(MergedMapChunksTest, TheLastFullMapIsTheServersMapAndAFreshChunkersToTheBit) {
  MergedMap map = TestMap();
  MapChunkerOptions options;
  options.chunk_poses = 16;
  options.max_moved_chunks = 2;
  MapChunker chunker(options);
  MergedMapAssembler assembler;
  ASSERT_TRUE(Deliver(chunker.Update(map, false, 0.05), &assembler));
  for (int64_t update = 2; update <= 12; ++update) {
    map.update = update;
    Correct(&map, 0.01);
    ASSERT_TRUE(Deliver(chunker.Update(map, false, 0.05), &assembler));
  }
  // Between full maps the subscriber's map lags: the budget left most moves behind.
  EXPECT_GT(MaxDifference(*assembler.map(), map), 0.01);
  // The run's end: a full map.
  map.update = 13;
  Correct(&map, 0.01);
  ASSERT_TRUE(Deliver(chunker.Update(map, /*full=*/true), &assembler));
  EXPECT_LT(MaxDifference(*assembler.map(), map), 1e-9);
  // A subscriber that saw only this map, from a chunker that saw only this map: the same
  // chunks, the same map, bit for bit.
  MapChunker fresh(options);
  const MapChunker::Split once = fresh.Update(map, /*full=*/true);
  MergedMapAssembler late;
  ASSERT_TRUE(Deliver(once, &late));
  const MergedMap& a = *assembler.map();
  const MergedMap& b = *late.map();
  ASSERT_EQ(a.trajectories.size(), b.trajectories.size());
  for (size_t t = 0; t < a.trajectories.size(); ++t) {
    ASSERT_EQ(a.trajectories[t].poses.size(), b.trajectories[t].poses.size());
    for (size_t i = 0; i < a.trajectories[t].poses.size(); ++i) {
      EXPECT_EQ(a.trajectories[t].poses[i].vector(), b.trajectories[t].poses[i].vector());
    }
    EXPECT_EQ(a.trajectories[t].T_global_local.vector(), b.trajectories[t].T_global_local.vector());
  }
  EXPECT_EQ(a.encounters, b.encounters);
}

}  // namespace
}  // namespace anchormap
