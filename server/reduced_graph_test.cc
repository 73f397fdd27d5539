// The reduced pose graph in the server (MappingServerOptions::reduced_graph): three robots
// lap one place (LoopWorld, a 23 m x 16 m floor, the size of one office tile) for 600 s of
// data; with the option the solver's poses stop growing once the place is mapped, every
// keyframe keeps a pose in the merged map, and the map stays as accurate.

#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "server/mapping_server.h"
#include "tests/scan_testing/scan_scenarios.h"

namespace anchormap {
namespace {

constexpr int64_t kStartUtime = 1'000'000;
constexpr int kKeyframes = 600;  // per robot, one per second of data
constexpr int kRobots = 3;

struct TeamInputs {
  std::vector<std::vector<Keyframe>> keyframes;  // per robot
  std::vector<std::vector<Pose2>> truth;         // per robot, per keyframe (world frame)
  std::vector<Encounter> encounters;
};

// Counter-clockwise laps round the block at 0.9 m per keyframe (the passes do not repeat the
// same points), the robots a third of the loop apart; R1 sees R2 and R3 early on.
const TeamInputs& Team() {
  static const TeamInputs team = [] {
    const testing::SyntheticWorld world = testing::LoopWorld();
    const std::vector<Pose2> laps =
        testing::RectanglePath({2.5, 2.0}, {17.5, 12.0}, 0.9, 14.0);  // 50 m a lap
    TeamInputs in;
    for (int r = 0; r < kRobots; ++r) {
      const size_t first = static_cast<size_t>(r) * 18;  // 16 m apart
      std::vector<Pose2> path(laps.begin() + static_cast<long>(first),
                              laps.begin() + static_cast<long>(first) + kKeyframes);
      std::vector<Keyframe> keyframes = testing::DriveKeyframes(
          world, path, "R" + std::to_string(r + 1), r + 1, kStartUtime,
          testing::OdometryNoise{0.01, 0.005}, 11 + static_cast<uint64_t>(r));
      for (Keyframe& k : keyframes) k.utime = kStartUtime + 2 * (k.utime - kStartUtime);  // 1 s
      in.keyframes.push_back(std::move(keyframes));
      in.truth.push_back(std::move(path));
    }
    for (int r = 1; r < kRobots; ++r) {
      const size_t i = static_cast<size_t>(2 * r);
      Encounter e;
      e.utime = in.keyframes[0][i].utime;
      e.observer = "R1";
      e.observer_trajectory_id = 1;
      e.observed = "R" + std::to_string(r + 1);
      e.T_observer_observed = Between(in.truth[0][i], in.truth[static_cast<size_t>(r)][i]);
      e.covariance = Eigen::Vector3d(0.0025, 0.0025, 0.0004).asDiagonal();
      e.seq = r - 1;
      in.encounters.push_back(e);
    }
    return in;
  }();
  return team;
}

struct TeamRun {
  int64_t variables_at_400s = 0;
  int64_t variables_at_end = 0;
  int64_t aliases = 0;
  size_t merged_poses = 0;
  bool every_trajectory_anchored = true;
  double ate_m = 0.0;  // RMSE of the keyframe positions in R1's first pose's frame
  std::string status_line;
};

TeamRun RunTeam(bool reduced) {
  const TeamInputs& team = Team();
  MappingServerOptions options;
  options.loop_closures = true;
  // Local candidates only: the laps' odometry never drifts beyond their windows, and the wide
  // searches were most of the test's time.
  options.loop.wide_search = false;
  options.solve_period_s = 0.5;  // the daemons' period
  options.match_workers = 0;
  options.reduced_graph.enabled = reduced;
  MappingServer server(options);
  TeamRun run;
  size_t next_encounter = 0;
  for (int i = 0; i < kKeyframes; ++i) {
    for (int r = 0; r < kRobots; ++r) {
      const Keyframe& k = team.keyframes[static_cast<size_t>(r)][static_cast<size_t>(i)];
      EXPECT_TRUE(server.OnKeyframe(k).ok());
      while (next_encounter < team.encounters.size() &&
             team.encounters[next_encounter].utime <= k.utime) {
        EXPECT_TRUE(server.OnEncounter(team.encounters[next_encounter++]).ok());
      }
    }
    if (i == 400) run.variables_at_400s = server.smoother().stats().variables;
  }
  server.Flush();
  run.variables_at_end = server.smoother().stats().variables;
  run.aliases = server.smoother().NumAliases();
  run.status_line = server.StatusLine();
  const MergedMap map = server.BuildMergedMap();
  double squared = 0.0;
  const Pose2& origin = team.truth[0][0];
  for (const MergedTrajectory& trajectory : map.trajectories) {
    run.merged_poses += trajectory.poses.size();
    run.every_trajectory_anchored = run.every_trajectory_anchored && trajectory.anchored;
    const size_t r = static_cast<size_t>(trajectory.robot[1] - '1');
    for (size_t i = 0; i < trajectory.poses.size(); ++i) {
      const Pose2 truth = Between(origin, team.truth[r][i]);
      squared += (truth.translation() - trajectory.poses[i].translation()).squaredNorm();
    }
  }
  run.ate_m = std::sqrt(squared / static_cast<double>(std::max<size_t>(1, run.merged_poses)));
  return run;
}

TEST(ReducedGraphTest, ThreeRobotsLappingOnePlaceStopAddingVariables) {
  const TeamRun full = RunTeam(false);
  const TeamRun reduced = RunTeam(true);
  SCOPED_TRACE("full: " + full.status_line);
  SCOPED_TRACE("reduced: " + reduced.status_line);
  // Without the option every keyframe is a variable (plus the anchors).
  EXPECT_EQ(full.aliases, 0);
  EXPECT_GE(full.variables_at_end, kRobots * kKeyframes);
  // With it, the last 200 s (600 keyframes) add fewer than 5 % of their keyframes as variables.
  const int64_t late_keyframes = kRobots * (kKeyframes - 1 - 400);
  EXPECT_LT(reduced.variables_at_end - reduced.variables_at_400s, late_keyframes / 20)
      << "variables at 400 s " << reduced.variables_at_400s << ", at the end "
      << reduced.variables_at_end;
  EXPECT_GT(reduced.aliases, kRobots * kKeyframes / 2);
  // Every keyframe keeps a pose in the merged map.
  EXPECT_EQ(reduced.merged_poses, static_cast<size_t>(kRobots * kKeyframes));
  EXPECT_EQ(full.merged_poses, static_cast<size_t>(kRobots * kKeyframes));
  EXPECT_TRUE(reduced.every_trajectory_anchored);
  // As accurate as the full graph, within 10 %.
  RecordProperty("ate_full_mm", static_cast<int>(1e3 * full.ate_m));
  RecordProperty("ate_reduced_mm", static_cast<int>(1e3 * reduced.ate_m));
  RecordProperty("variables_full", static_cast<int>(full.variables_at_end));
  RecordProperty("variables_reduced_400s", static_cast<int>(reduced.variables_at_400s));
  RecordProperty("variables_reduced_end", static_cast<int>(reduced.variables_at_end));
  EXPECT_LT(reduced.ate_m, 1.1 * full.ate_m)
      << "ATE full " << full.ate_m << " m, reduced " << reduced.ate_m << " m";
}

TEST(ReducedGraphTest, WithTheOptionTheServerNeitherSnapshotsNorDefersUpdates) {
  MappingServerOptions options;
  EXPECT_TRUE(MappingServer(options).CanSnapshot());
  EXPECT_TRUE(MappingServer(options).CanDeferUpdates());
  options.reduced_graph.enabled = true;
  MappingServer server(options);
  EXPECT_FALSE(server.CanSnapshot());      // the aliases are not in the snapshot format
  EXPECT_FALSE(server.CanDeferUpdates());  // the fold reads the estimate
  EXPECT_FALSE(server.BeginDeferredUpdates());
  ASSERT_NE(server.folder(), nullptr);
  EXPECT_NE(server.StatusLine().find("reduced graph: nodes 0"), std::string::npos);
}

}  // namespace
}  // namespace anchormap
