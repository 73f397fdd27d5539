// anchormap-eval as a process, on small logs written here with common/bus/lcm_log.h.

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <unistd.h>

#include <gtest/gtest.h>

#include "anchormap/merged_map_t.hpp"
#include "bot_core/pose_t.hpp"
#include "common/bus/lcm_log.h"
#include "common/geometry/pose2.h"
#include "tests/testing/file_contents.h"
#include "tests/testing/scratch.h"

namespace anchormap {
namespace {

namespace fs = std::filesystem;

using ::anchormap::testing::ScratchPath;

struct RunResult {
  int exit_code = -1;
  std::string out;
  std::string err;
};

RunResult RunEval(const std::string& arguments) {
  const std::string out = ScratchPath("am_eval_cli.out"), err = ScratchPath("am_eval_cli.err");
  const std::string command = std::string(ANCHORMAP_BINARY_DIR) + "/bin/anchormap-eval " +
                              arguments + " >" + out + " 2>" + err;
  const int status = std::system(command.c_str());
  RunResult result{WIFEXITED(status) ? WEXITSTATUS(status) : -1,
                   ::anchormap::testing::FileContents(out),
                   ::anchormap::testing::FileContents(err)};
  fs::remove(out);
  fs::remove(err);
  return result;
}

// Truth: R1 at (i, 0), R2 at (i, 2), i = 0..4, one pose a second.
// Map: both anchored in a global frame rotated by 0.4 rad and moved; R2 1 m off in y.
class EvalCliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    truth_ = ScratchPath("am_eval_cli_truth.lcmlog");
    map_ = ScratchPath("am_eval_cli_map.lcmlog");
    LcmLogWriter truth;
    ASSERT_TRUE(truth.Open(truth_).ok());
    merged_map_t map{};
    map.update = 7;
    const Pose2 global(10.0, -3.0, 0.4);
    for (int r = 0; r < 2; ++r) {
      trajectory_t t{};
      t.robot = r == 0 ? "R1" : "R2";
      t.trajectory_id = r + 1;
      t.anchored = true;
      for (int i = 0; i < 5; ++i) {
        const int64_t utime = 1000000LL * i;
        bot_core::pose_t pose{};
        pose.utime = utime;
        pose.pos[0] = i;
        pose.pos[1] = 2.0 * r;
        pose.orientation[0] = 1.0;
        ASSERT_TRUE(truth.Write(t.robot + "_GROUND_TRUTH", utime, pose).ok());
        const Pose2 estimated = Compose(global, Pose2(i, 3.0 * r, 0.0));
        t.pose_utimes.push_back(utime);
        t.poses.push_back({estimated.x(), estimated.y(), estimated.theta()});
      }
      t.num_poses = 5;
      map.trajectories.push_back(t);
    }
    for (int i = 0; i <= 8; ++i) {  // R2's odometry, every 0.5 s, in a frame of its own
      bot_core::pose_t odometry{};
      odometry.utime = 500000LL * i;
      odometry.pos[0] = 100.0 + 0.5 * i;
      odometry.orientation[0] = 1.0;
      ASSERT_TRUE(truth.Write("R2_ODOMETRY", odometry.utime, odometry).ok());
    }
    map.num_trajectories = 2;
    map.encounters.push_back({"R1", 1, 0, "R2", 2, 0, /*kind: direct*/ 0});
    map.num_encounters = 1;
    LcmLogWriter out;
    ASSERT_TRUE(out.Open(map_).ok());
    ASSERT_TRUE(out.Write("ANCHORMAP_MERGED_MAP", 0, map).ok());
  }
  void TearDown() override {
    fs::remove(truth_);
    fs::remove(map_);
  }
  std::string truth_, map_;
};

TEST_F(EvalCliTest, AteTableAndJson) {
  const RunResult table = RunEval("--map " + map_ + " --truth " + truth_);
  ASSERT_EQ(table.exit_code, 0) << table.err;
  EXPECT_NE(table.out.find("merged map update 7"), std::string::npos) << table.out;
  EXPECT_NE(table.out.find("merged = one alignment for R1 R2"), std::string::npos) << table.out;
  const RunResult json = RunEval("--map " + map_ + " --truth " + truth_ + " --json");
  ASSERT_EQ(json.exit_code, 0) << json.err;
  EXPECT_EQ(json.out.front(), '{');
  EXPECT_EQ(json.out.substr(json.out.size() - 2), "}\n");
  // Per robot exact; merged 0.5 m everywhere (see map_evaluation_test).
  EXPECT_NE(json.out.find("\"label\": \"R1\""), std::string::npos);
  EXPECT_NE(json.out.find("\"label\": \"merged\", \"members\": [\"R1\", \"R2\"]"),
            std::string::npos)
      << json.out;
  EXPECT_NE(json.out.find("\"rmse\": 0.5,"), std::string::npos) << json.out;
}

TEST_F(EvalCliTest, RelationsOnOneRobot) {
  // R2's estimate moves 1 m per second along its own x: relation (0, 2) of 2 m is exact, the
  // relation (1, 3) claims 2.5 m and 0.1 rad: errors 0.5 and 0.1.
  const std::string relations = ScratchPath("am_eval_cli.relations");
  std::ofstream(relations) << "0.0 2.0 2.0 0 0 0 0 0\n1.0 3.0 2.5 0 0 0 0 0.1\n";
  const RunResult result =
      RunEval("--relations " + relations + " --map " + map_ + " --robot R2 --json");
  ASSERT_EQ(result.exit_code, 0) << result.err;
  EXPECT_NE(result.out.find("\"evaluated\": 2"), std::string::npos) << result.out;
  EXPECT_NE(result.out.find("\"translation_m\": {\"count\": 2, \"mean\": 0.25,"), std::string::npos)
      << result.out;
  EXPECT_NE(result.out.find("\"rotation_rad\": {\"count\": 2, \"mean\": 0.05,"), std::string::npos)
      << result.out;
  fs::remove(relations);
}

TEST_F(EvalCliTest, RelationsBetweenKeyframesNeedTheOdometry) {
  // 0.5 s and 2.5 s are no keyframe times. With the odometry: X(0.5) = keyframe 0 + 0.5 m,
  // X(2.5) = keyframe 2 + 0.5 m, 2 m apart; the relation claims 2.2 m: error 0.2.
  const std::string relations = ScratchPath("am_eval_cli_between.relations");
  std::ofstream(relations) << "0.5 2.5 2.2 0 0 0 0 0\n";
  const std::string common = "--relations " + relations + " --map " + map_ + " --robot R2 --json";
  const RunResult keyframes_only = RunEval(common);
  EXPECT_EQ(keyframes_only.exit_code, 1);
  EXPECT_NE(keyframes_only.out.find("\"no_pose_near\": 1"), std::string::npos)
      << keyframes_only.out;
  const RunResult completed = RunEval(common + " --odometry " + truth_);
  ASSERT_EQ(completed.exit_code, 0) << completed.err;
  EXPECT_NE(completed.out.find("\"completed_trajectories\": 1"), std::string::npos);
  // No <R>_TIME_REPAIR in that log: no relation end moved.
  EXPECT_NE(completed.out.find("\"time_repaired_ends\": 0"), std::string::npos);
  EXPECT_NE(completed.out.find("\"translation_m\": {\"count\": 1, \"mean\": 0.2,"),
            std::string::npos)
      << completed.out;
  fs::remove(relations);
}

TEST_F(EvalCliTest, BadCommandLinesAndInputs) {
  EXPECT_EQ(RunEval("--help").exit_code, 0);
  EXPECT_EQ(RunEval("--bogus").exit_code, 2);
  EXPECT_EQ(RunEval("--truth " + truth_).exit_code, 2);  // no --map
  EXPECT_EQ(RunEval("--map " + map_).exit_code, 2);      // neither mode
  EXPECT_EQ(RunEval("--map " + map_ + " --truth x --relations y").exit_code, 2);
  EXPECT_EQ(RunEval("--map " + map_ + " --truth " + truth_ + " --max-time-gap-s -1").exit_code, 2);
  const RunResult missing = RunEval("--map /nonexistent/map.lcmlog --truth " + truth_);
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_NE(missing.err.find("/nonexistent/map.lcmlog"), std::string::npos) << missing.err;
  // The truth log as the map: no merged map in it.
  const RunResult no_map = RunEval("--map " + truth_ + " --truth " + truth_);
  EXPECT_EQ(no_map.exit_code, 1);
  EXPECT_NE(no_map.err.find("no complete merged map"), std::string::npos) << no_map.err;
}

}  // namespace
}  // namespace anchormap
