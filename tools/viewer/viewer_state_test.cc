#include "tools/viewer/viewer_state.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "tools/viewer/base64.h"

namespace anchormap::viewer {
namespace {

using nlohmann::json;

// What the page does with a message (tools/viewer/web/viewer.js, applyMessage), on a
// canonical JSON model: full resets, delta patches.
void ApplyToModel(const json& m, json* model) {
  json& s = *model;
  if (m["type"] == "full")
    s = {{"trajectories", json::object()},
         {"links", json::array()},
         {"tiles", json::object()},
         {"covariances", nullptr},
         {"status", nullptr}};
  s["seq"] = m["seq"];
  s["restarts"] = m["restarts"];
  s["map_update"] = m["map_update"];
  s["map_utime"] = m["map_utime"];
  s["wall_utime"] = m["wall_utime"];
  for (const auto& key : m["removed"]) s["trajectories"].erase(key.get<std::string>());
  for (const auto& t : m["trajectories"]) {
    json& mine = s["trajectories"][t["key"].get<std::string>()];
    if (mine.is_null()) mine = {{"poses", json::array()}};
    mine["robot"] = t["robot"];
    mine["id"] = t["id"];
    mine["anchored"] = t["anchored"];
    mine["anchor"] = t["anchor"];
    std::vector<double> poses = mine["poses"].get<std::vector<double>>();
    poses.resize(std::min(poses.size(), 3 * t["from"].get<size_t>()));
    for (const auto& v : t["poses"]) poses.push_back(v.get<double>());
    poses.resize(3 * t["num_poses"].get<size_t>());
    mine["poses"] = poses;
  }
  if (m.contains("encounters")) {
    std::vector<json> links = s["links"].get<std::vector<json>>();
    links.resize(std::min(links.size(), m["encounters"]["from"].get<size_t>()));
    for (const auto& l : m["encounters"]["links"]) links.push_back(l);
    s["links"] = links;
  }
  if (m["clear_tiles"].get<bool>()) s["tiles"] = json::object();
  for (const auto& key : m["removed_tiles"]) s["tiles"].erase(key.get<std::string>());
  for (const auto& t : m["tiles"]) {
    s["tiles"][std::to_string(t["x"].get<int>()) + "," + std::to_string(t["y"].get<int>())] = t;
  }
  if (m.contains("covariances")) s["covariances"] = m["covariances"];
  if (m.contains("status")) s["status"] = m["status"];
}

MergedTrajectory Trajectory(const std::string& robot, int64_t id, int n, double shift = 0.0) {
  MergedTrajectory t;
  t.robot = robot;
  t.trajectory_id = id;
  for (int i = 0; i < n; ++i) {
    t.poses.emplace_back(0.5 * i + shift, 0.1 * i * i, 0.01 * i);
    t.pose_utimes.push_back(i * 100000);
  }
  return t;
}

GridTile Tile(int x, int y, int8_t fill, int64_t update = 1) {
  GridTile tile;
  tile.update = update;
  tile.tile_x = x;
  tile.tile_y = y;
  tile.width = 4;
  tile.height = 3;
  tile.cells.assign(12, fill);
  tile.cells[5] = -1;
  return tile;
}

// The page after full states vs after deltas, at every step.
class DeltaChain {
 public:
  void Step() {
    ApplyToModel(state.TakeDelta(), &by_deltas);
    json by_full;
    ApplyToModel(state.Full(), &by_full);
    ASSERT_EQ(by_deltas, by_full) << "after delta " << state.seq();
  }
  ViewerState state;
  json by_deltas;
  void Start() { ApplyToModel(state.Full(), &by_deltas); }
};

TEST(ViewerStateTest, AFullStateThenEachDeltaEqualsTheNextFullState) {
  DeltaChain chain;
  chain.Start();
  std::mt19937 random(7);
  std::uniform_real_distribution<double> noise(-0.05, 0.05);
  MergedMap map;
  map.trajectories = {Trajectory("R1", 11, 3), Trajectory("R2", 12, 2), Trajectory("R10", 13, 0)};
  for (int step = 1; step <= 40; ++step) {
    map.update = step;
    map.utime = 1000000 * step;
    for (MergedTrajectory& t : map.trajectories) {  // grow
      const int n = static_cast<int>(t.poses.size());
      t.poses.emplace_back(0.5 * n, 0.3 * n, 0.02 * n);
      t.pose_utimes.push_back(100000 * n);
    }
    if (step % 7 == 0) {  // a loop closure moves a whole trajectory
      for (Pose2& p : map.trajectories[0].poses) p = Pose2(p.x() + noise(random), p.y(), p.theta());
      map.trajectories[0].anchored = true;
      map.trajectories[0].T_global_local = Pose2(1.0, 2.0, 0.3);
    }
    if (step % 5 == 0) map.encounters.push_back({"R1", 11, step / 5, "R2", 12, 1});
    if (step == 20) map.encounters.erase(map.encounters.begin());          // reordered list
    if (step == 25) map.trajectories.erase(map.trajectories.begin() + 1);  // R2 gone
    if (step == 30) map.trajectories.push_back(Trajectory("R2", 99, 4));   // R2's new session
    ASSERT_TRUE(chain.state.ApplyMergedMap(map, 5000 + step));
    if (step % 3 == 0) {
      ASSERT_TRUE(
          chain.state.ApplyGridTile(Tile(step % 4, -1, static_cast<int8_t>(step), step), 0));
    }
    if (step % 4 == 0) {
      AnchorCovariances c;
      c.update = step;
      c.anchors.push_back({"R1", 11, Pose2(1, 2, 0.3), Eigen::Matrix3d::Identity() * step});
      ASSERT_TRUE(chain.state.ApplyAnchorCovariances(c, 0));
    }
    if (step % 6 == 0) {
      ServerStatus s;
      s.update = step;
      s.keyframes = 3 * step;
      s.rejections = {{"not_finite", step}};
      ASSERT_TRUE(chain.state.ApplyStatus(s, 0));
    }
    chain.Step();
    if (step % 9 == 0) chain.Step();  // an empty delta changes nothing
  }
  EXPECT_EQ(chain.by_deltas["trajectories"].size(), 3u);
  EXPECT_EQ(chain.by_deltas["trajectories"]["R1/11"]["poses"].size(), 3u * 43);
  EXPECT_EQ(chain.by_deltas["trajectories"]["R2/99"]["poses"].size(), 3u * 14);
  EXPECT_EQ(chain.by_deltas["tiles"].size(), 4u);
  EXPECT_EQ(chain.by_deltas["status"]["keyframes"], 108);
}

TEST(ViewerStateTest, DeltasCarryOnlyWhatChanged) {
  ViewerState state;
  MergedMap map;
  map.update = 1;
  map.trajectories = {Trajectory("R1", 1, 5), Trajectory("R2", 2, 5)};
  ASSERT_TRUE(state.ApplyMergedMap(map, 0));
  ASSERT_TRUE(state.ApplyGridTile(Tile(0, 0, 10), 0));
  json first = state.TakeDelta();
  EXPECT_EQ(first["trajectories"].size(), 2u);
  EXPECT_EQ(first["trajectories"][0]["from"], 0);
  EXPECT_EQ(first["trajectories"][0]["poses"].size(), 15u);
  EXPECT_EQ(first["tiles"].size(), 1u);

  // R1 gains a keyframe; R2's pose 3 moves by 2 cm, its pose 4 by 0.2 mm (below 1 mm);
  // the tile comes again unchanged.
  map.update = 2;
  map.trajectories[0].poses.emplace_back(9.0, 9.0, 0.0);
  Pose2& p3 = map.trajectories[1].poses[3];
  p3 = Pose2(p3.x() + 0.02, p3.y(), p3.theta());
  ASSERT_TRUE(state.ApplyMergedMap(map, 0));
  ASSERT_TRUE(state.ApplyGridTile(Tile(0, 0, 10), 0));
  json second = state.TakeDelta();
  ASSERT_EQ(second["trajectories"].size(), 2u);
  EXPECT_EQ(second["trajectories"][0]["key"], "R1/1");
  EXPECT_EQ(second["trajectories"][0]["from"], 5);
  EXPECT_EQ(second["trajectories"][0]["num_poses"], 6);
  EXPECT_EQ(second["trajectories"][0]["poses"], json({9.0, 9.0, 0.0}));
  EXPECT_EQ(second["trajectories"][1]["from"], 3);
  EXPECT_EQ(second["trajectories"][1]["poses"].size(), 6u);
  EXPECT_TRUE(second["tiles"].empty());

  map.update = 3;
  Pose2& p4 = map.trajectories[1].poses[4];
  p4 = Pose2(p4.x() + 0.0002, p4.y(), p4.theta());
  ASSERT_TRUE(state.ApplyMergedMap(map, 0));
  json third = state.TakeDelta();
  EXPECT_TRUE(third["trajectories"].empty()) << third.dump();
  EXPECT_FALSE(third.contains("encounters"));
  EXPECT_FALSE(third.contains("status"));
  EXPECT_EQ(third["map_update"], 3);
  EXPECT_FALSE(state.HasChanges());
}

TEST(ViewerStateTest, ATileTravelsAsBase64OfItsCells) {
  ViewerState state;
  ASSERT_TRUE(state.ApplyGridTile(Tile(-2, 5, 100), 0));
  const json tile = state.Full()["tiles"][0];
  EXPECT_EQ(tile["x"], -2);
  EXPECT_EQ(tile["y"], 5);
  const auto cells = Base64Decode(tile["cells"].get<std::string>());
  ASSERT_TRUE(cells.has_value());
  ASSERT_EQ(cells->size(), 12u);
  EXPECT_EQ((*cells)[0], 100);
  EXPECT_EQ((*cells)[5], 255);  // -1, unknown
}

TEST(ViewerStateTest, AnUpdateNumberGoingBackIsAServerRestart) {
  ViewerState state;
  MergedMap map;
  map.update = 50;
  map.trajectories = {Trajectory("R1", 1, 5)};
  ASSERT_TRUE(state.ApplyMergedMap(map, 0));
  ASSERT_TRUE(state.ApplyGridTile(Tile(0, 0, 10, 50), 0));
  (void)state.TakeDelta();
  ASSERT_TRUE(state.ApplyGridTile(Tile(0, 0, 10, 50), 0));  // the same update again
  EXPECT_EQ(state.restarts(), 0);
  MergedMap after;
  after.update = 2;
  after.trajectories = {Trajectory("R1", 7, 2)};
  ASSERT_TRUE(state.ApplyMergedMap(after, 0));
  EXPECT_EQ(state.restarts(), 1);
  EXPECT_EQ(state.num_tiles(), 0u);
  const json delta = state.TakeDelta();
  EXPECT_EQ(delta["restarts"], 1);
  EXPECT_EQ(delta["removed"], json({"R1/1"}));
  EXPECT_TRUE(delta["clear_tiles"].get<bool>());
  EXPECT_EQ(delta["trajectories"].size(), 1u);
}

// A server restarted from its journal keeps its update numbers: its new instance id (in
// the status message) tells. One restart is counted once, whichever tells first.
TEST(ViewerStateTest, ANewInstanceIdIsAServerRestartCountedOnce) {
  ViewerState state;
  ServerStatus status;
  status.update = 40;
  status.instance_id = 111;
  ASSERT_TRUE(state.ApplyStatus(status, 0));
  status.update = 41;
  ASSERT_TRUE(state.ApplyStatus(status, 0));
  EXPECT_EQ(state.restarts(), 0);
  status.instance_id = 222;  // resumed from its journal: the same update numbers
  ASSERT_TRUE(state.ApplyStatus(status, 0));
  EXPECT_EQ(state.restarts(), 1);
  // Without a journal: the update number goes back first, then the new id arrives.
  status.update = 50;
  ASSERT_TRUE(state.ApplyStatus(status, 0));
  MergedMap map;
  map.update = 3;
  map.trajectories = {Trajectory("R1", 1, 2)};
  ASSERT_TRUE(state.ApplyMergedMap(map, 0));
  map.update = 60;
  ASSERT_TRUE(state.ApplyMergedMap(map, 0));
  map.update = 2;  // back again: the restart, inferred
  ASSERT_TRUE(state.ApplyMergedMap(map, 0));
  EXPECT_EQ(state.restarts(), 2);
  status.update = 2;
  status.instance_id = 333;  // the same restart, told again
  ASSERT_TRUE(state.ApplyStatus(status, 0));
  EXPECT_EQ(state.restarts(), 2);
  status.instance_id = 0;  // an offline run's outputs carry none: no restart
  status.update = 3;
  ASSERT_TRUE(state.ApplyStatus(status, 0));
  EXPECT_EQ(state.restarts(), 2);
}

TEST(ViewerStateTest, EncountersGetTheirKindAndLinksToUnknownTrajectoriesAreRefused) {
  ViewerState state;
  MergedMap map;
  map.update = 1;
  map.trajectories = {Trajectory("R1", 1, 5), Trajectory("R2", 2, 5)};
  map.encounters = {{"R1", 1, 2, "R2", 2, 3, ConstraintKind::kDirectEncounter},
                    {"R1", 1, 0, "R1", 1, 4, ConstraintKind::kLoopClosure},
                    {"R1", 1, 1, "R1", 77, 0, ConstraintKind::kScanEncounter}};
  ASSERT_TRUE(state.ApplyMergedMap(map, 0));
  const json links = state.Full()["encounters"]["links"];
  ASSERT_EQ(links.size(), 2u);
  EXPECT_EQ(links[0], json({"R1/1", 2, "R2/2", 3, "direct"}));
  EXPECT_EQ(links[1][4], "loop");
  EXPECT_EQ(state.rejections().count(ErrorCode::kInvalidValue), 1);
}

TEST(ViewerStateTest, ATileThatTheLastGridRunsDidNotRefreshIsDropped) {
  ViewerStateOptions options;
  options.max_grid_runs_back = 2;
  ViewerState state(options);
  json model;
  ApplyToModel(state.Full(), &model);
  ASSERT_TRUE(state.ApplyGridTile(Tile(0, 0, 1, 1), 0));  // run 1: tiles (0,0), (1,0)
  ASSERT_TRUE(state.ApplyGridTile(Tile(1, 0, 1, 1), 0));
  ApplyToModel(state.TakeDelta(), &model);
  for (int64_t update = 2; update <= 4; ++update) {  // runs 2..4 bring (1,0) only
    ASSERT_TRUE(state.ApplyGridTile(Tile(1, 0, static_cast<int8_t>(update), update), 0));
    const json delta = state.TakeDelta();
    ApplyToModel(delta, &model);
    // (0,0) was last brought by run 1: kept while run - 1 <= 2, dropped at run 4.
    EXPECT_EQ(delta["removed_tiles"].size(), update == 4 ? 1u : 0u) << update;
  }
  EXPECT_EQ(state.num_tiles(), 1u);
  EXPECT_EQ(model["tiles"].size(), 1u);
  EXPECT_TRUE(model["tiles"].contains("1,0"));
  json full;
  ApplyToModel(state.Full(), &full);
  EXPECT_EQ(model, full);
}

TEST(ViewerStateTest, TilesBeyondTheLimitsAreRefused) {
  ViewerStateOptions options;
  options.max_tiles = 2;
  options.max_tile_side_cells = 8;
  ViewerState state(options);
  EXPECT_TRUE(state.ApplyGridTile(Tile(0, 0, 1), 0));
  EXPECT_TRUE(state.ApplyGridTile(Tile(1, 0, 1), 0));
  EXPECT_FALSE(state.ApplyGridTile(Tile(2, 0, 1), 0));  // a third tile
  EXPECT_TRUE(state.ApplyGridTile(Tile(1, 0, 2), 0));   // an update of a held one
  GridTile big = Tile(0, 0, 1);
  big.width = 9;
  big.cells.assign(27, 0);
  EXPECT_FALSE(state.ApplyGridTile(big, 0));
  GridTile wrong = Tile(0, 0, 1);
  wrong.cells.pop_back();
  EXPECT_FALSE(state.ApplyGridTile(wrong, 0));
  EXPECT_EQ(state.num_tiles(), 2u);
  EXPECT_EQ(state.rejections().count(ErrorCode::kQueueFull), 1);
  EXPECT_EQ(state.rejections().count(ErrorCode::kAbsurdSize), 1);
  EXPECT_EQ(state.rejections().count(ErrorCode::kInvalidValue), 1);
}

}  // namespace
}  // namespace anchormap::viewer
