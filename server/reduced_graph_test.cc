// The reduced pose graph in the server (MappingServerOptions::reduced_graph): three robots
// lap one place (LoopWorld, a 23 m x 16 m floor, the size of one office tile) for 600 s of
// data; with the option the solver's poses stop growing once the place is mapped, every
// keyframe keeps a pose in the merged map, and the map stays as accurate. A server with the
// option restored from a snapshot continues as the uninterrupted one.

#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/util/log.h"
#include "server/mapping_server.h"
#include "server/snapshot_codec.h"
#include "tests/scan_testing/scan_scenarios.h"
#include "tests/testing/map_difference.h"

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

TEST(ReducedGraphTest, WithTheOptionTheServerSnapshotsButDefersNoUpdates) {
  MappingServerOptions options;
  EXPECT_TRUE(MappingServer(options).CanSnapshot());
  EXPECT_TRUE(MappingServer(options).CanDeferUpdates());
  options.reduced_graph.enabled = true;
  MappingServer server(options);
  EXPECT_TRUE(server.CanSnapshot());       // the aliases and the folder are in the format
  EXPECT_FALSE(server.CanDeferUpdates());  // the fold reads the estimate
  EXPECT_FALSE(server.BeginDeferredUpdates());
  ASSERT_NE(server.folder(), nullptr);
  EXPECT_NE(server.StatusLine().find("reduced graph: nodes 0"), std::string::npos);
}

// --- Snapshots (server/snapshot_codec.h, version 12) ---

// The team's first `keyframes` seconds as the server gets them (RunTeam's order).
struct TeamInput {
  bool is_keyframe = true;
  Keyframe keyframe;
  Encounter encounter;
};
std::vector<TeamInput> TeamInputsUpTo(int keyframes) {
  const TeamInputs& team = Team();
  std::vector<TeamInput> out;
  size_t next_encounter = 0;
  for (int i = 0; i < keyframes; ++i) {
    for (int r = 0; r < kRobots; ++r) {
      const Keyframe& k = team.keyframes[static_cast<size_t>(r)][static_cast<size_t>(i)];
      out.push_back({true, k, {}});
      while (next_encounter < team.encounters.size() &&
             team.encounters[next_encounter].utime <= k.utime) {
        out.push_back({false, {}, team.encounters[next_encounter++]});
      }
    }
  }
  return out;
}

void Feed(MappingServer* server, const TeamInput& in) {
  const Status status =
      in.is_keyframe ? server->OnKeyframe(in.keyframe) : server->OnEncounter(in.encounter);
  EXPECT_TRUE(status.ok()) << status.message();
}

MappingServerOptions TeamOptions(bool reduced) {
  MappingServerOptions options;  // RunTeam's
  options.loop_closures = true;
  options.loop.wide_search = false;
  options.solve_period_s = 0.5;
  options.match_workers = 0;
  options.reduced_graph.enabled = reduced;
  return options;
}

// The status line without this process's figures: the last update's time and the loop
// closures' submap cache (rebuilt on demand after a restore: snapshot_codec.h).
std::string WithoutProcessFigures(std::string line) {
  const size_t from = line.find("last update ");
  line.erase(from, line.find(" ms", from) - from);
  const size_t cache = line.find("loop_submaps:");
  if (cache != std::string::npos) line.erase(cache, line.find(';', cache) - cache);
  return line;
}

// The two servers' counters, links, folds and maps: the same (every figure of the status line,
// the reduced graph's included).
void ExpectSameRun(const MappingServer& a, const MappingServer& b) {
  EXPECT_EQ(WithoutProcessFigures(a.StatusLine()), WithoutProcessFigures(b.StatusLine()));
  EXPECT_EQ(a.stats().updates, b.stats().updates);
  EXPECT_EQ(a.stats().added_by_kind, b.stats().added_by_kind);
  EXPECT_EQ(a.encounter_links(), b.encounter_links());
  EXPECT_EQ(a.smoother().stats().variables, b.smoother().stats().variables);
  EXPECT_EQ(a.smoother().stats().batch_steps, b.smoother().stats().batch_steps);
  EXPECT_EQ(a.smoother().NumAliases(), b.smoother().NumAliases());
  EXPECT_EQ(a.smoother().measurements_inside_nodes(), b.smoother().measurements_inside_nodes());
  for (const TrajectoryId t : a.smoother().Trajectories()) {
    EXPECT_EQ(a.smoother().NextBorrowedNode(t), b.smoother().NextBorrowedNode(t));
  }
  ASSERT_NE(a.folder(), nullptr);
  ASSERT_NE(b.folder(), nullptr);
  EXPECT_EQ(a.folder()->num_nodes(), b.folder()->num_nodes());
  EXPECT_EQ(a.folder()->StatsLine(), b.folder()->StatsLine());
  EXPECT_EQ(testing::LargestPoseDifference(a.BuildMergedMap(), b.BuildMergedMap()), 0.0);
}

class ReducedGraphSnapshotTest : public ::testing::Test {
 protected:
  void SetUp() override { SetMinLogLevel(LogLevel::kError); }
  void TearDown() override { SetMinLogLevel(LogLevel::kInfo); }
};

// A server with the option, snapshot at three moments of the team's laps (keyframes folding,
// nodes borrowed, a solve pending), restored into a new server and fed the rest, ends as the
// uninterrupted one: the same folds, counters, links and status line, the same map (0
// difference) and the same snapshot bytes (every field: graph edits with the aliases,
// smoother, folder, sources).
TEST_F(ReducedGraphSnapshotTest, ARestoredServerFoldsAsTheUninterruptedOne) {
  const std::vector<TeamInput> inputs = TeamInputsUpTo(240);  // four laps and more
  const size_t n = inputs.size();
  const MappingServerOptions options = TeamOptions(true);
  MappingServer live(options);
  const std::vector<size_t> cuts = {n / 3, n / 2 + 1, 4 * n / 5 + 2};
  std::vector<std::vector<uint8_t>> snapshots;
  std::vector<int64_t> aliases_at_cuts;
  int pending_at_cuts = 0;
  for (size_t i = 0; i < n; ++i) {
    Feed(&live, inputs[i]);
    if (std::find(cuts.begin(), cuts.end(), i + 1) == cuts.end()) continue;
    ASSERT_TRUE(live.CanSnapshot());
    SnapshotNodeState node;
    node.position = {static_cast<int64_t>(i + 1), inputs[i].keyframe.utime, "KEYFRAMES"};
    Result<std::vector<uint8_t>> bytes = SnapshotCodec::Encode(live, node);
    ASSERT_TRUE(bytes.ok()) << bytes.status().message();
    snapshots.push_back(std::move(*bytes));
    aliases_at_cuts.push_back(live.smoother().NumAliases());
    pending_at_cuts += live.solve_pending() ? 1 : 0;
  }
  live.Flush();
  const Result<std::vector<uint8_t>> live_bytes = SnapshotCodec::Encode(live, {});
  ASSERT_TRUE(live_bytes.ok()) << live_bytes.status().message();
  // The run folds from the first snapshot on, borrows nodes, and one snapshot falls inside a
  // solve period.
  SCOPED_TRACE(live.StatusLine());
  ASSERT_EQ(snapshots.size(), cuts.size());
  EXPECT_GT(aliases_at_cuts.front(), 0);
  EXPECT_GT(live.smoother().NumAliases(), aliases_at_cuts.back());
  EXPECT_GT(live.folder()->stats().folded, kRobots * 240 / 2);
  int64_t borrowed = 0;
  for (const TrajectoryId t : live.smoother().Trajectories()) {
    borrowed += live.smoother().NextBorrowedNode(t).index - kBorrowedNodeIndexBase;
  }
  EXPECT_GT(borrowed, 0);
  EXPECT_GT(pending_at_cuts, 0);

  // The last snapshot's size against the full graph's at the same inputs (recorded, for the
  // docs: 1,120,294 against 1,405,687 bytes at 03017c1 + snap25).
  MappingServer full(TeamOptions(false));
  for (size_t i = 0; i < cuts.back(); ++i) Feed(&full, inputs[i]);
  const Result<std::vector<uint8_t>> full_bytes = SnapshotCodec::Encode(full, {});
  ASSERT_TRUE(full_bytes.ok());
  RecordProperty("snapshot_bytes_reduced", static_cast<int>(snapshots.back().size()));
  RecordProperty("snapshot_bytes_full", static_cast<int>(full_bytes->size()));

  for (size_t c = 0; c < cuts.size(); ++c) {
    SCOPED_TRACE("snapshot after input " + std::to_string(cuts[c]) + " of " + std::to_string(n));
    MappingServer restored(options);
    SnapshotNodeState read;
    const Status decoded =
        SnapshotCodec::Decode(snapshots[c].data(), snapshots[c].size(), &restored, &read);
    ASSERT_TRUE(decoded.ok()) << decoded.message();
    EXPECT_EQ(restored.smoother().NumAliases(), aliases_at_cuts[c]);
    // Round trip: the restored server's snapshot is the same bytes.
    const Result<std::vector<uint8_t>> again = SnapshotCodec::Encode(restored, read);
    ASSERT_TRUE(again.ok());
    EXPECT_TRUE(*again == snapshots[c]);
    for (size_t i = cuts[c]; i < n; ++i) Feed(&restored, inputs[i]);
    restored.Flush();
    ExpectSameRun(live, restored);
    const Result<std::vector<uint8_t>> end = SnapshotCodec::Encode(restored, {});
    ASSERT_TRUE(end.ok());
    EXPECT_TRUE(*end == *live_bytes);
  }
}

// Snapshots without the reduced graph (an older version, or a server without the option) still
// load into a server with it (the option switched on at a restart): every pose is a node, and the
// restored server folds from there, the same from either format. The other way round, and a
// snapshot of a server with the option in a format before version 12, are refused.
TEST_F(ReducedGraphSnapshotTest, SnapshotsWithoutTheReducedGraphLoadIntoAServerWithIt) {
  const std::vector<TeamInput> inputs = TeamInputsUpTo(150);
  const size_t cut = inputs.size() / 2;
  MappingServer full(TeamOptions(false));
  for (size_t i = 0; i < cut; ++i) Feed(&full, inputs[i]);
  const Result<std::vector<uint8_t>> v11 = SnapshotCodec::EncodeVersion(full, {}, 11);
  const Result<std::vector<uint8_t>> v12 = SnapshotCodec::Encode(full, {});
  ASSERT_TRUE(v11.ok() && v12.ok());
  const int64_t poses = full.smoother().stats().variables - full.num_anchored();

  std::vector<std::unique_ptr<MappingServer>> restored;
  for (const std::vector<uint8_t>* bytes : {&*v11, &*v12}) {
    restored.push_back(std::make_unique<MappingServer>(TeamOptions(true)));
    SnapshotNodeState read;
    const Status decoded =
        SnapshotCodec::Decode(bytes->data(), bytes->size(), restored.back().get(), &read);
    ASSERT_TRUE(decoded.ok()) << decoded.message();
    EXPECT_EQ(static_cast<int64_t>(restored.back()->folder()->num_nodes()), poses);
    for (size_t i = cut; i < inputs.size(); ++i) Feed(restored.back().get(), inputs[i]);
    restored.back()->Flush();
  }
  for (size_t i = cut; i < inputs.size(); ++i) Feed(&full, inputs[i]);
  full.Flush();
  // The restored servers fold the second half's revisits; every keyframe keeps its pose.
  EXPECT_EQ(full.smoother().NumAliases(), 0);
  EXPECT_GT(restored[0]->smoother().NumAliases(), static_cast<int64_t>(inputs.size()) / 4);
  EXPECT_EQ(restored[0]->stats().solver_problems, 0);
  size_t merged_poses = 0;
  for (const MergedTrajectory& t : restored[0]->BuildMergedMap().trajectories) {
    merged_poses += t.poses.size();
  }
  EXPECT_EQ(merged_poses, static_cast<size_t>(kRobots * 150));
  ExpectSameRun(*restored[0], *restored[1]);

  // Refused: a snapshot of the reduced graph into a server without it (its aliases would stay,
  // no keyframe would fold or borrow a node after them), and in a format that cannot hold it.
  const Result<std::vector<uint8_t>> folded = SnapshotCodec::Encode(*restored[0], {});
  ASSERT_TRUE(folded.ok());
  MappingServer without(TeamOptions(false));
  SnapshotNodeState read;
  const Status refused = SnapshotCodec::Decode(folded->data(), folded->size(), &without, &read);
  EXPECT_EQ(refused.code(), ErrorCode::kDecodeFailed);
  EXPECT_NE(refused.message().find("reduced graph"), std::string::npos) << refused.message();
  const Result<std::vector<uint8_t>> old = SnapshotCodec::EncodeVersion(*restored[0], {}, 11);
  ASSERT_FALSE(old.ok());
  EXPECT_EQ(old.status().code(), ErrorCode::kInvalidArgument);
}

// --- The publication by node (MapPublisher: KeyframeMoves in the grid and the chunker) ---

// The grid as MapPublisher::UpdateGrid made it before it went by node (the oracle below): a
// scan of every keyframe of the grid's trajectories for its displacement, the farthest moved
// traced again first within the budget, the keyframes of trajectories that left taken out.
void UpdateGridByScan(const MapPublisher& publisher, const MappingServer& server,
                      KeyframeGrid* grid) {
  const MapPublisherOptions& options = publisher.options();
  const Smoother& smoother = server.smoother();
  const TrajectoryTable& table = server.table();
  struct Moved {
    double displacement;
    uint64_t key;
    const LaserScan* scan;
    Pose2 pose;
  };
  std::vector<Moved> moved;
  std::set<uint64_t> current;
  int64_t inserted = 0;
  for (const TrajectoryId id : publisher.GridTrajectories(smoother, table)) {
    const TrajectoryRecord* record = table.FindBySolverId(id);
    const std::vector<Pose2> poses = smoother.GlobalTrajectory(id);
    for (size_t i = 0; i < poses.size() && i < record->scans.size(); ++i) {
      const uint64_t key = (static_cast<uint64_t>(id.value()) << 32) | i;
      current.insert(key);
      const std::optional<double> d = grid->Displacement(key, poses[i]);
      if (!d) {
        grid->Place(key, record->scans[i], poses[i]);
        ++inserted;
      } else if (*d > grid->move_tolerance_m()) {
        moved.push_back({*d, key, &record->scans[i], poses[i]});
      }
    }
  }
  std::stable_sort(moved.begin(), moved.end(),
                   [](const Moved& a, const Moved& b) { return a.displacement > b.displacement; });
  const double budget = std::min(
      static_cast<double>(options.grid_max_moved),
      options.grid_min_moved + options.grid_moved_per_inserted * static_cast<double>(inserted));
  for (size_t n = 0; n < moved.size() && n < static_cast<size_t>(budget); ++n) {
    grid->Place(moved[n].key, *moved[n].scan, moved[n].pose);
  }
  std::vector<uint64_t> gone;
  for (const auto& [key, pose] : grid->placed()) {
    if (current.count(key) == 0) gone.push_back(key);
  }
  for (const uint64_t key : gone) {
    grid->Remove(key, table.FindBySolverId(TrajectoryId(static_cast<int64_t>(key >> 32)))
                          ->scans[key & 0xffffffffu]);
  }
}

using PublicationByNodeTest = ReducedGraphSnapshotTest;

// The team's laps published as the daemons do (a map every 4 inputs, a grid every 12), with
// the option (keyframes folded onto nodes, some of other robots) and without it (every
// keyframe its own node): the grid placed at the same poses, bit for bit, with the same
// tiles, as one kept by a scan of every keyframe; the same chunks sent, with the same bits,
// as a chunker that reads every chunk.
TEST_F(PublicationByNodeTest, SameGridAndChunksAsAScanOfEveryKeyframe) {
  const std::vector<TeamInput> inputs = TeamInputsUpTo(200);
  for (const bool reduced : {true, false}) {
    SCOPED_TRACE(reduced ? "reduced" : "every keyframe a node");
    MappingServerOptions server_options = TeamOptions(reduced);
    // Chunks of 16 keyframes: most are not sent for new keyframes, so their moves decide.
    server_options.publish.chunks.chunk_poses = 16;
    MappingServer server(server_options);
    ASSERT_EQ(server.smoother().options().formulation, Formulation::kRelative);
    const MapPublisherOptions& options = server.publisher().options();
    KeyframeGrid grid_by_scan(options.grid, options.grid_move_tolerance_cells);
    MapChunker chunker_reading_all(options.chunks);
    std::optional<int64_t> last_map;
    for (size_t i = 0; i < inputs.size(); ++i) {
      Feed(&server, inputs[i]);
      if (i % 4 != 3) continue;
      const int64_t now = static_cast<int64_t>(i) * 250'000;
      const MapChunker::Split split = server.SplitMergedMap(now, /*full=*/false);
      // The reader of every chunk, with MapPublisher::Refresh's share.
      double refresh = 1.0;
      if (last_map)
        refresh = 1e-6 * static_cast<double>(now - *last_map) / options.map_full_period_s;
      last_map = now;
      std::vector<MapChunker::Trajectory> views;
      for (const TrajectoryRecord& record : server.table().records()) {
        const Smoother& smoother = server.smoother();
        const int poses = smoother.NumPoses(record.solver_id);
        if (record.num_keyframes() == 0 || poses == 0) continue;
        MapChunker::Trajectory t;
        t.robot = record.robot;
        t.trajectory_id = record.agent_trajectory_id;
        t.anchored = smoother.IsAnchored(record.solver_id);
        if (const auto anchor = smoother.Anchor(record.solver_id)) t.T_global_local = *anchor;
        t.num_poses = poses;
        t.pose_utimes = &record.utimes;
        const TrajectoryId id = record.solver_id;
        t.local_poses = [&smoother, id](int64_t first, int64_t end, Pose2* out) {
          for (int64_t k = first; k < end; ++k) {
            out[k - first] = smoother.FramePose(PoseKey{id, static_cast<int32_t>(k)});
          }
        };
        views.push_back(std::move(t));
      }
      const MapChunker::Split expected =
          chunker_reading_all.Update(server.update_count(), server.update_count(), views,
                                     server.encounter_links(), refresh >= 1.0, refresh);
      ASSERT_EQ(split.chunks.size(), expected.chunks.size()) << "input " << i;
      for (size_t c = 0; c < expected.chunks.size(); ++c) {
        const MergedMapChunk& a = split.chunks[c];
        const MergedMapChunk& b = expected.chunks[c];
        EXPECT_EQ(a.robot, b.robot);
        EXPECT_EQ(a.trajectory_id, b.trajectory_id);
        EXPECT_EQ(a.chunk_index, b.chunk_index);
        EXPECT_EQ(a.version, b.version);
        EXPECT_EQ(a.pose_utimes, b.pose_utimes);
        EXPECT_EQ(a.encounters, b.encounters);
        ASSERT_EQ(a.local_poses.size(), b.local_poses.size());
        for (size_t k = 0; k < a.local_poses.size(); ++k) {
          EXPECT_EQ(a.local_poses[k].x(), b.local_poses[k].x());
          EXPECT_EQ(a.local_poses[k].y(), b.local_poses[k].y());
          EXPECT_EQ(a.local_poses[k].theta(), b.local_poses[k].theta());
        }
      }
      ASSERT_EQ(split.header.trajectories.size(), expected.header.trajectories.size());
      for (size_t t = 0; t < expected.header.trajectories.size(); ++t) {
        EXPECT_EQ(split.header.trajectories[t].chunk_versions,
                  expected.header.trajectories[t].chunk_versions);
      }
      if (i % 12 != 11) continue;
      (void)server.BuildChangedGridTiles();
      UpdateGridByScan(server.publisher(), server, &grid_by_scan);
      const auto& placed = server.publisher().grid().placed();
      ASSERT_EQ(placed.size(), grid_by_scan.placed().size()) << "input " << i;
      for (const auto& [key, pose] : grid_by_scan.placed()) {
        ASSERT_EQ(placed.count(key), 1u);
        EXPECT_EQ(placed.at(key).x(), pose.x());
        EXPECT_EQ(placed.at(key).y(), pose.y());
        EXPECT_EQ(placed.at(key).theta(), pose.theta());
      }
    }
    EXPECT_EQ(server.smoother().NumAliases() > 0, reduced);
    const std::vector<GridTile> tiles = server.publisher().grid().Tiles(0, 0);
    const std::vector<GridTile> expected_tiles = grid_by_scan.Tiles(0, 0);
    ASSERT_EQ(tiles.size(), expected_tiles.size());
    for (size_t t = 0; t < tiles.size(); ++t) EXPECT_EQ(tiles[t].cells, expected_tiles[t].cells);
  }
}

}  // namespace
}  // namespace anchormap
