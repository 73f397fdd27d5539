#include "server/map_publisher.h"

#include <cmath>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "common/geometry/angle.h"
#include "tests/testing/straight_keyframes.h"

namespace anchormap {
namespace {

// Two robots driving along their own x axes, 1 m per keyframe; each keyframe's scan is one
// beam straight ahead hitting a wall 2 m away. Robot B starts at (10, 5) facing north in
// A's frame; one encounter joins them.
class MapPublisherTest : public ::testing::Test {
 protected:
  static constexpr int kKeyframes = 4;

  MapPublisherTest() {
    for (const char* robot : {"A", "B"}) {
      const int64_t trajectory = robot[0] == 'A' ? 7 : 8;
      for (int32_t seq = 0; seq < kKeyframes; ++seq) {
        const Keyframe k = testing::StraightKeyframe(robot, trajectory, seq);
        std::vector<AdmittedKeyframe> admitted;
        EXPECT_TRUE(table_.Offer(k, &admitted).ok());
        for (const AdmittedKeyframe& a : admitted) {
          EXPECT_TRUE(smoother_.AddPose(a.key, a.T_local_pose).ok());
          if (a.previous) {
            EXPECT_TRUE(
                smoother_
                    .AddBetween(*a.previous, a.key, a.T_previous_this, a.T_previous_this_covariance)
                    .ok());
          }
        }
      }
    }
    EXPECT_EQ(smoother_.Update().status.ToString(), "ok");
  }

  // A's pose 2 sees B's pose 1, exactly.
  void Encounter() {
    const Pose2 world_T_b0(10.0, 5.0, kPi / 2);
    const Pose2 seen = Between(Pose2(2.0, 0.0, 0.0), Compose(world_T_b0, Pose2(1.0, 0.0, 0.0)));
    ASSERT_TRUE(smoother_
                    .AddEncounter({TrajectoryId(0), 2}, {TrajectoryId(1), 1}, seen,
                                  Eigen::Vector3d(1e-2, 1e-2, 1e-3).asDiagonal())
                    .ok());
    ASSERT_TRUE(smoother_.Update().status.ok());
    links_.push_back({"A", 7, 2, "B", 8, 1});
  }

  // A loop closure that bends A: its last keyframe 0.6 m to the side of its first's heading,
  // the ones between pulled less (keyframes 1 to 3 move; 0 holds the gauge).
  void BendA() {
    ASSERT_TRUE(smoother_
                    .AddBetween({TrajectoryId(0), 0}, {TrajectoryId(0), kKeyframes - 1},
                                Pose2(kKeyframes - 1.0, 0.6, 0.0),
                                Eigen::Vector3d(1e-6, 1e-6, 1e-6).asDiagonal())
                    .ok());
    ASSERT_TRUE(smoother_.Update().status.ok());
  }

  TrajectoryTable table_;
  Smoother smoother_;
  std::vector<EncounterLink> links_;
};

TEST_F(MapPublisherTest, MergedMapHoldsEveryTrajectoryLocalUntilAnchoredThenGlobal) {
  MapPublisher publisher;
  const MergedMap before = publisher.BuildMergedMap(smoother_, table_, links_, 42, 1);
  EXPECT_EQ(before.utime, 42);
  EXPECT_EQ(before.update, 1);
  ASSERT_EQ(before.trajectories.size(), 2u);
  for (const MergedTrajectory& t : before.trajectories) {
    EXPECT_FALSE(t.anchored) << t.robot;
    ASSERT_EQ(t.poses.size(), static_cast<size_t>(kKeyframes));
    EXPECT_LT(PoseError(t.poses[3], Pose2(3.0, 0.0, 0.0)).norm(), 1e-9) << t.robot;
    EXPECT_EQ(t.pose_utimes[3], 4'000'000);
  }

  Encounter();
  const MergedMap after = publisher.BuildMergedMap(smoother_, table_, links_, 43, 2);
  ASSERT_EQ(after.trajectories.size(), 2u);
  const MergedTrajectory& a = after.trajectories[0];
  const MergedTrajectory& b = after.trajectories[1];
  EXPECT_EQ(a.robot, "A");
  EXPECT_EQ(b.trajectory_id, 8);
  EXPECT_TRUE(a.anchored && b.anchored);
  // A's frame is the global frame; B's anchor is its start in A's frame, and its poses are
  // the anchor composed with its local poses.
  EXPECT_LT(PoseError(a.T_global_local, Pose2()).norm(), 1e-9);
  EXPECT_LT(PoseError(b.T_global_local, Pose2(10.0, 5.0, kPi / 2)).norm(), 1e-9);
  for (int i = 0; i < kKeyframes; ++i) {
    EXPECT_LT(PoseError(b.poses[i], Compose(b.T_global_local, Pose2(i, 0.0, 0.0))).norm(), 1e-9);
  }
  ASSERT_EQ(after.encounters.size(), 1u);
  EXPECT_EQ(after.encounters[0].index_b, 1);
}

// The global poses a subscriber makes of a split (MergedMapAssembler's formula: the
// header's anchor composed with each chunk's local poses), assuming it holds `held`'s
// chunks, by trajectory and index.
std::vector<std::vector<Pose2>> Assembled(
    const MapChunker::Split& split,
    const std::map<std::pair<int64_t, int32_t>, MergedMapChunk>& held) {
  std::vector<std::vector<Pose2>> out;
  for (const MergedMapHeader::Trajectory& t : split.header.trajectories) {
    out.emplace_back();
    for (size_t k = 0; k < t.chunk_versions.size(); ++k) {
      const MergedMapChunk& chunk = held.at({t.trajectory_id, static_cast<int32_t>(k)});
      EXPECT_EQ(chunk.version, t.chunk_versions[k]);
      for (const Pose2& local : chunk.local_poses) {
        out.back().push_back(Compose(t.T_global_local, local));
      }
    }
  }
  return out;
}

TEST_F(MapPublisherTest, SplitFromTheSmootherGivesGlobalTrajectorysBitsOnceFull) {
  MapPublisherOptions options;
  options.chunks.chunk_poses = 1;  // a chunk per keyframe
  options.chunks.max_moved_chunks = 1;
  options.map_full_period_s = 2.0;
  MapPublisher publisher(options);
  std::map<std::pair<int64_t, int32_t>, MergedMapChunk> held;
  std::map<std::pair<int64_t, int32_t>, int64_t> sent_at;
  int64_t now = 0;
  const auto split = [&](int64_t update, bool full) {
    const MapChunker::Split out =
        publisher.SplitMergedMap(smoother_, table_, links_, now, update, now, full);
    for (const MergedMapChunk& c : out.chunks) {
      held[{c.trajectory_id, c.chunk_index}] = c;
      sent_at[{c.trajectory_id, c.chunk_index}] = now;
    }
    return out;
  };
  const MapChunker::Split first = split(1, false);  // the first map: every chunk
  EXPECT_EQ(first.chunks.size(), 2u * kKeyframes);
  Encounter();
  BendA();
  // Maps every 0.5 s: A's bend (keyframes 1 to 3 moved) goes one chunk per map, the
  // farthest moved first; besides, 8 x 0.5 / 2 = 2 chunks per map, the least recently
  // sent: every chunk within the 2 s period.
  for (int64_t update = 2; update <= 12; ++update) {
    now += 500'000;
    const MapChunker::Split out = split(update, false);
    // Update 2 also sends B's chunk 1, where the encounter ends.
    EXPECT_LE(out.chunks.size(), (update == 2 ? 2u : 1u) + 2u) << update;
    if (update == 2) {
      // The refresh took A's chunks 0 and 1 (all sent at the first map: the chunks' order);
      // of the moved 2 and 3, the budget took 3, which moved farther.
      std::vector<std::pair<int64_t, int32_t>> ids;
      for (const MergedMapChunk& c : out.chunks) ids.emplace_back(c.trajectory_id, c.chunk_index);
      EXPECT_EQ(ids, (std::vector<std::pair<int64_t, int32_t>>{{7, 0}, {7, 1}, {7, 3}, {8, 1}}));
    }
    for (const auto& [chunk, at] : sent_at) EXPECT_LE(now - at, 2'000'000) << update;
  }
  // A full map: the subscriber's global poses are GlobalTrajectory's, bit for bit, and the
  // merged map's (which goes through the global frame and back) up to round-off.
  now += 500'000;
  const MapChunker::Split full = split(13, true);
  EXPECT_EQ(full.chunks.size(), 2u * kKeyframes);
  const std::vector<std::vector<Pose2>> assembled = Assembled(full, held);
  const MergedMap merged = publisher.BuildMergedMap(smoother_, table_, links_, now, 13);
  ASSERT_EQ(assembled.size(), 2u);
  for (size_t t = 0; t < 2; ++t) {
    const std::vector<Pose2> global = smoother_.GlobalTrajectory(TrajectoryId(static_cast<int>(t)));
    ASSERT_EQ(assembled[t].size(), global.size());
    for (size_t i = 0; i < global.size(); ++i) {
      EXPECT_EQ(assembled[t][i].vector(), global[i].vector()) << t << " " << i;
      EXPECT_LT(PoseError(assembled[t][i], merged.trajectories[t].poses[i]).norm(), 1e-12);
    }
  }
  EXPECT_EQ(full.header.num_encounters, 1);
}

TEST_F(MapPublisherTest, AnchorCovariancesAreTheSmoothersMarginals) {
  MapPublisher publisher;
  EXPECT_TRUE(publisher.BuildAnchorCovariances(&smoother_, table_, 1, 1).anchors.empty());
  Encounter();
  const AnchorCovariances out = publisher.BuildAnchorCovariances(&smoother_, table_, 5, 2);
  ASSERT_EQ(out.anchors.size(), 2u);
  EXPECT_EQ(out.anchors[1].robot, "B");
  EXPECT_EQ(out.anchors[1].trajectory_id, 8);
  const Eigen::Matrix3d expected = smoother_.MarginalCovariance(Key(AnchorKey{TrajectoryId(1)}));
  // The same marginal by a sparse solve instead of the block recursion: round-off apart.
  EXPECT_LT((out.anchors[1].covariance - expected).norm(), 1e-12 * expected.norm());
  EXPECT_EQ(out.anchors[1].covariance, out.anchors[1].covariance.transpose());
  // B's anchor is known through one encounter and A's odometry: looser than A's, which
  // carries the group's gauge prior.
  EXPECT_GT(out.anchors[1].covariance.trace(), out.anchors[0].covariance.trace());
}

TEST_F(MapPublisherTest, GridComesFromTheLargestGroupWithWallsWhereTheScansHit) {
  MapPublisherOptions options;
  options.grid.resolution_m = 0.1;
  MapPublisher publisher(options);
  // Before the encounter the two groups are equal: the first one (A) is drawn.
  EXPECT_EQ(publisher.GridTrajectories(smoother_, table_),
            (std::vector<TrajectoryId>{TrajectoryId(0)}));
  Encounter();
  EXPECT_EQ(publisher.GridTrajectories(smoother_, table_),
            (std::vector<TrajectoryId>{TrajectoryId(0), TrajectoryId(1)}));

  const std::vector<GridTile> tiles = publisher.BuildGridTiles(smoother_, table_, 9, 2);
  ASSERT_FALSE(tiles.empty());
  auto occupancy_at = [&](double x, double y) {
    const int64_t cx = static_cast<int64_t>(std::floor(x / 0.1));
    const int64_t cy = static_cast<int64_t>(std::floor(y / 0.1));
    for (const GridTile& t : tiles) {
      const int64_t local_x = cx - int64_t{t.tile_x} * t.width;
      const int64_t local_y = cy - int64_t{t.tile_y} * t.height;
      if (local_x >= 0 && local_x < t.width && local_y >= 0 && local_y < t.height) {
        return static_cast<int>(t.cells[static_cast<size_t>(local_y * t.width + local_x)]);
      }
    }
    return -1;
  };
  // A's last keyframe at (3, 0) sees a wall at (5, 0); B's at (10, 8) facing north sees
  // one at (10, 10). Between the last sensor and its wall (4.5, 0): free.
  EXPECT_GT(occupancy_at(5.05, 0.05), 50);
  EXPECT_GT(occupancy_at(10.05, 10.05), 50);
  EXPECT_GE(occupancy_at(4.55, 0.05), 0);
  EXPECT_LT(occupancy_at(4.55, 0.05), 50);
  EXPECT_EQ(occupancy_at(-20.0, -20.0), -1);
}

// The grid is kept across publications: A alone first; the encounter brings B's keyframes
// in (only the tiles they reach go out); nothing moved since: nothing goes out; and the
// grid equals one built from scratch at the poses it holds, within a cell of the estimate.
TEST_F(MapPublisherTest, GridIsUpdatedByWhatMovedAndSendsOnlyChangedTiles) {
  MapPublisherOptions options;
  options.grid.resolution_m = 0.1;
  options.grid.tile_size_cells = 16;
  MapPublisher publisher(options);
  const size_t tiles_of_a = publisher.BuildGridTiles(smoother_, table_, 1, 1).size();
  EXPECT_EQ(publisher.UpdateGrid(smoother_, table_).inserted, 0);
  Encounter();
  const std::vector<GridTile> changed = publisher.BuildChangedGridTiles(smoother_, table_, 2, 2);
  EXPECT_GT(changed.size(), 0u);
  EXPECT_EQ(publisher.grid().num_tiles(), tiles_of_a + changed.size());  // B's tiles are new
  EXPECT_TRUE(publisher.BuildChangedGridTiles(smoother_, table_, 3, 3).empty());
  KeyframeGrid scratch(options.grid);
  for (const auto& [key, pose] : publisher.grid().placed()) {
    const TrajectoryId id(static_cast<int64_t>(key >> 32));
    const size_t index = key & 0xffffffffu;
    const Pose2 estimate = smoother_.GlobalTrajectory(id)[index];
    EXPECT_LE((estimate.translation() - pose.translation()).norm(), 0.1);
    scratch.Place(key, table_.FindBySolverId(id)->scans[index], pose);
  }
  EXPECT_EQ(publisher.grid().placed().size(), 2u * kKeyframes);
  const std::vector<GridTile> expected = scratch.Tiles(3, 3),
                              actual = publisher.BuildGridTiles(smoother_, table_, 3, 3);
  ASSERT_EQ(actual.size(), expected.size());
  for (size_t i = 0; i < expected.size(); ++i) EXPECT_EQ(actual[i].cells, expected[i].cells);
}

// A bounded publication traces again at most grid_max_moved of the keyframes that moved, the
// farthest first; the next publications (or a complete one) catch up with the rest.
TEST_F(MapPublisherTest, GridTracesAgainAtMostMaxMovedFarthestFirst) {
  MapPublisherOptions options;
  options.grid.resolution_m = 0.1;
  options.grid_max_moved = 1;
  MapPublisher publisher(options);
  EXPECT_EQ(publisher.UpdateGrid(smoother_, table_).inserted, kKeyframes);  // A alone
  ASSERT_NO_FATAL_FAILURE(BendA());
  const auto key = [](int index) { return static_cast<uint64_t>(index); };  // trajectory 0
  const Pose2 before_1 = publisher.grid().placed().at(key(1));
  const MapPublisher::GridChange first = publisher.UpdateGrid(smoother_, table_);
  EXPECT_EQ(first.moved, 1);
  EXPECT_EQ(first.deferred, 2);  // keyframes 1 and 2 (0 holds the gauge and did not move)
  const std::vector<Pose2> estimate = smoother_.GlobalTrajectory(TrajectoryId(0));
  EXPECT_EQ(publisher.grid().placed().at(key(kKeyframes - 1)).y(), estimate.back().y());
  EXPECT_EQ(publisher.grid().placed().at(key(1)).y(), before_1.y());
  EXPECT_EQ(publisher.UpdateGrid(smoother_, table_).moved, 1);  // then keyframe 2
  EXPECT_EQ(publisher.grid().placed().at(key(2)).y(), estimate[2].y());
  // A complete grid takes the rest at once: every keyframe within the tolerance of the
  // estimate, and the grid equal to one built from scratch at the poses it holds.
  EXPECT_EQ(publisher.UpdateGrid(smoother_, table_, /*complete=*/true).deferred, 0);
  KeyframeGrid scratch(options.grid);
  for (int i = 0; i < kKeyframes; ++i) {
    const Pose2 placed = publisher.grid().placed().at(key(i));
    EXPECT_LE(std::abs(placed.y() - estimate[static_cast<size_t>(i)].y()), 1e-9);
    scratch.Place(key(i), table_.FindBySolverId(TrajectoryId(0))->scans[static_cast<size_t>(i)],
                  placed);
  }
  const std::vector<GridTile> expected = scratch.Tiles(3, 3),
                              actual = publisher.BuildGridTiles(smoother_, table_, 3, 3);
  ASSERT_EQ(actual.size(), expected.size());
  for (size_t i = 0; i < expected.size(); ++i) EXPECT_EQ(actual[i].cells, expected[i].cells);
}

// The work counters (the status's "grid work" and "chunk work") sum what the calls did.
TEST_F(MapPublisherTest, WorkSumsTheGridChangesAndTheChunksSent) {
  MapPublisherOptions options;
  options.grid.resolution_m = 0.1;
  options.grid_max_moved = 1;
  options.chunks.chunk_poses = 1;
  MapPublisher publisher(options);
  const MapPublisher::GridChange first = publisher.UpdateGrid(smoother_, table_);
  ASSERT_NO_FATAL_FAILURE(BendA());
  const MapPublisher::GridChange second = publisher.UpdateGrid(smoother_, table_);
  const MapPublisher::GridWork& grid = publisher.grid_work();
  EXPECT_EQ(grid.updates, 2);
  EXPECT_EQ(grid.inserted, first.inserted + second.inserted);
  EXPECT_EQ(grid.inserted, kKeyframes);  // A alone
  EXPECT_EQ(grid.moved, 1);
  EXPECT_EQ(grid.deferred, 2);
  EXPECT_EQ(grid.moves_found, 3);  // keyframes 1 to 3
  EXPECT_EQ(grid.rebuilds, 0);
  const MapChunker::Split split = publisher.SplitMergedMap(smoother_, table_, links_, 0, 1, 0);
  const MapChunker::Work& chunks = publisher.chunk_work();
  EXPECT_EQ(chunks.updates, 1);
  EXPECT_EQ(chunks.chunks, 2 * kKeyframes);
  EXPECT_EQ(chunks.sent, static_cast<int64_t>(split.chunks.size()));
  EXPECT_EQ(chunks.sent, 2 * kKeyframes);  // the first map: every chunk
  EXPECT_EQ(chunks.read, 0);
  EXPECT_NE(publisher.WorkSummary().find("grid work: updates 2 inserted 4 moved 1 deferred 2"),
            std::string::npos)
      << publisher.WorkSummary();
}

// A complete grid where more keyframes moved than stayed is made again (one trace per
// keyframe): the same tiles and cells as the grid that caught up by bounded publications.
TEST_F(MapPublisherTest, CompleteGridMadeAgainEqualsTheOneMovedKeyframeByKeyframe) {
  MapPublisherOptions options;
  options.grid.resolution_m = 0.1;
  options.grid.tile_size_cells = 16;
  options.grid_max_moved = 1;
  MapPublisher made_again(options), moved_one_by_one(options);
  for (MapPublisher* publisher : {&made_again, &moved_one_by_one}) {
    EXPECT_EQ(publisher->UpdateGrid(smoother_, table_).inserted, kKeyframes);  // A alone
  }
  ASSERT_NO_FATAL_FAILURE(BendA());
  int rounds = 0;
  while (moved_one_by_one.UpdateGrid(smoother_, table_).deferred > 0) ++rounds;
  EXPECT_EQ(rounds, 2);
  const MapPublisher::GridChange change =
      made_again.UpdateGrid(smoother_, table_, /*complete=*/true);
  EXPECT_EQ(change.moved, 3);
  EXPECT_EQ(change.deferred, 0);
  EXPECT_EQ(change.removed, 0);
  ASSERT_EQ(made_again.grid().placed().size(), moved_one_by_one.grid().placed().size());
  for (const auto& [key, pose] : moved_one_by_one.grid().placed()) {
    EXPECT_EQ(made_again.grid().placed().at(key).y(), pose.y());
  }
  const std::vector<GridTile> expected = moved_one_by_one.BuildGridTiles(smoother_, table_, 3, 3),
                              actual = made_again.BuildGridTiles(smoother_, table_, 3, 3);
  ASSERT_EQ(actual.size(), expected.size());
  for (size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(actual[i].tile_x, expected[i].tile_x);
    EXPECT_EQ(actual[i].tile_y, expected[i].tile_y);
    EXPECT_EQ(actual[i].cells, expected[i].cells);
  }
}

// Without a floor, a publication traces again as many moved keyframes as
// grid_moved_per_inserted allows for the keyframes it traces in: none while nothing new comes
// in, then (B's keyframes join the grid) the deferred ones.
TEST_F(MapPublisherTest, GridTracesAgainInProportionToTheKeyframesTracedIn) {
  MapPublisherOptions options;
  options.grid.resolution_m = 0.1;
  options.grid_min_moved = 0;
  options.grid_moved_per_inserted = 1.0;
  MapPublisher publisher(options);
  EXPECT_EQ(publisher.UpdateGrid(smoother_, table_).inserted, kKeyframes);  // A alone
  ASSERT_NO_FATAL_FAILURE(BendA());
  const MapPublisher::GridChange idle = publisher.UpdateGrid(smoother_, table_);
  EXPECT_EQ(idle.inserted, 0);
  EXPECT_EQ(idle.moved, 0);
  EXPECT_EQ(idle.deferred, 3);  // A's keyframes 1 to 3 (0 holds the gauge)
  Encounter();
  const MapPublisher::GridChange joined = publisher.UpdateGrid(smoother_, table_);
  EXPECT_EQ(joined.inserted, kKeyframes);  // B's
  EXPECT_EQ(joined.moved, 3);
  EXPECT_EQ(joined.deferred, 0);
  // The floor alone: one per publication while nothing new comes in.
  options.grid_min_moved = 1;
  options.grid_moved_per_inserted = 0.0;
  MapPublisher floored(options);
  EXPECT_EQ(floored.UpdateGrid(smoother_, table_).inserted, 2 * kKeyframes);
  ASSERT_TRUE(smoother_
                  .AddBetween({TrajectoryId(0), 0}, {TrajectoryId(0), kKeyframes - 1},
                              Pose2(kKeyframes - 1.0, -0.6, 0.0),
                              Eigen::Vector3d(1e-6, 1e-6, 1e-6).asDiagonal())
                  .ok());
  ASSERT_TRUE(smoother_.Update().status.ok());
  const MapPublisher::GridChange once = floored.UpdateGrid(smoother_, table_);
  EXPECT_EQ(once.moved, 1);
  EXPECT_GT(once.deferred, 0);
}

TEST(MapPublisherRateTest, MapAfterEachNewUpdateAtMostOncePerPeriodGridOnItsOwnPeriod) {
  MapPublisherOptions options;
  options.map_period_s = 1.0;
  options.grid_period_s = 5.0;
  MapPublisher publisher(options);
  EXPECT_FALSE(publisher.MapDue(0, 0));  // no update yet
  EXPECT_TRUE(publisher.MapDue(0, 1));
  publisher.MarkMapPublished(0, 1);
  EXPECT_FALSE(publisher.MapDue(5'000'000, 1));  // nothing new
  EXPECT_FALSE(publisher.MapDue(999'999, 2));    // too soon
  EXPECT_TRUE(publisher.MapDue(1'000'000, 2));
  EXPECT_TRUE(publisher.GridDue(0, 1));
  publisher.MarkGridPublished(0, 1);
  EXPECT_FALSE(publisher.GridDue(4'999'999, 3));
  EXPECT_TRUE(publisher.GridDue(5'000'000, 3));
  options.grid_period_s = 0.0;  // never
  EXPECT_FALSE(MapPublisher(options).GridDue(100'000'000, 9));
}

}  // namespace
}  // namespace anchormap
