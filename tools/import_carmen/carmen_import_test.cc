#include "tools/import_carmen/carmen_import.h"

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "tests/testing/data_path.h"
#include "tests/testing/scratch.h"

namespace anchormap {
namespace {

std::string WriteTemp(const std::string& name, const std::string& text) {
  const std::string path = ::anchormap::testing::ScratchPath(name);
  std::ofstream(path) << text;
  return path;
}

// The shape of a corrected log (../shared/data/carmen): each FLASER is followed by an ODOM
// line repeating its pose with time stamp 0, then a NEFF line.
const char* kCorrectedLog =
    "# message formats defined: PARAM SYNC ODOM FLASER\n"
    "PARAM robot_frontlaser_offset 0.0 nohost 0\n"
    "ODOM 0 0 0 0 0 0 0.1 pippo 0.1\n"
    "ODOM 0.1 0 0 0 0 0 0.2 pippo 0.2\n"
    "FLASER 2 1.0 2.0 0.5 0.1 0.2 0.5 0.1 0.2 0.2 pippo 0.2\n"
    "ODOM 0.5 0.1 0.2 0 0 0 0 pippo 0\n"
    "NEFF 15\n"
    "ODOM 0.6 0.1 0.2 0 0 0 0.3 pippo 0.3\n"
    "FLASER 1 1.0 0.7 0.1 0.2 0.7 0.1 0.2 3.5 pippo 3.5\n"
    "ODOM 0.7 0.1 0.2 0 0 0 1.2 pippo 1.2\n";  // bogus, not zero

TEST(ReadCarmenLogTest, CountsTypesAndDetectsTheCorrectedSignature) {
  const std::string path = WriteTemp("am_corrected.log", kCorrectedLog);
  CarmenLogContents contents;
  ASSERT_TRUE(ReadCarmenLog(path, false, &contents).ok());
  const CarmenLogStats& s = contents.stats;
  EXPECT_EQ(s.lines, 10);
  EXPECT_EQ(s.odometry_lines, 5);
  EXPECT_EQ(s.flaser_lines, 2);
  EXPECT_EQ(s.comment_or_blank_lines, 1);
  EXPECT_EQ(s.ignored_by_type.at("PARAM"), 1);
  EXPECT_EQ(s.ignored_by_type.at("NEFF"), 1);
  EXPECT_EQ(s.reanchored_odometry_lines, 2);
  EXPECT_EQ(s.odometry_steps_back, 0);  // the re-anchoring lines took the scans' times
  EXPECT_EQ(contents.odometry[2].ipc_time_s, 0.2);
  EXPECT_EQ(contents.odometry[4].ipc_time_s, 3.5);
  EXPECT_EQ(contents.odometry[2].pose.x(), 0.5);
  EXPECT_TRUE(contents.LooksCorrected());
  EXPECT_EQ(s.scans_by_beam_count.at(2), 1);
  EXPECT_EQ(s.scans_by_beam_count.at(1), 1);
  std::filesystem::remove(path);
}

TEST(ReadCarmenLogTest, StandingStillInARawLogIsNotReanchoring) {
  // Same pose after the scan but with a real (even earlier) time stamp: raw odometry.
  const std::string path = WriteTemp("am_raw.log",
                                     "FLASER 1 1.0 0 0 0 0 0 0 5.0 h 5.0\n"
                                     "ODOM 0 0 0 0 0 0 4.9 h 4.9\n"
                                     "ODOM 0 0 0 0 0 0 4.8 h 4.8\n"
                                     "FLASER 1 1.0 0 0 0 0 0 0 4.7 h 4.7\n");
  CarmenLogContents contents;
  ASSERT_TRUE(ReadCarmenLog(path, false, &contents).ok());
  EXPECT_EQ(contents.stats.reanchored_odometry_lines, 0);
  EXPECT_FALSE(contents.LooksCorrected());
  EXPECT_EQ(contents.stats.odometry_steps_back, 1);
  EXPECT_EQ(contents.stats.laser_steps_back, 1);
  std::filesystem::remove(path);
}

TEST(ReadCarmenLogTest, StrictFailsWithFileAndLineLenientSkipsAndCounts) {
  const std::string path = WriteTemp("am_malformed.log",
                                     "ODOM 0 0 0 0 0 0 0.1 h 0.1\n"
                                     "ODOM 0 0 zero 0 0 0 0.2 h 0.2\n"
                                     "FLASER 2 1.0 0 0 0 0 0 0 0.3 h 0.3\n"
                                     "ODOM 0 0 0 0 0 0 0.4 h 0.4\n");
  CarmenLogContents contents;
  EXPECT_EQ(ReadCarmenLog(path, false, &contents).message(),
            path + ":2: ODOM: theta 'zero' is not a finite number");
  ASSERT_TRUE(ReadCarmenLog(path, true, &contents).ok());
  EXPECT_EQ(contents.stats.malformed_lines, 2);
  EXPECT_EQ(contents.stats.odometry_lines, 2);
  EXPECT_EQ(contents.stats.flaser_lines, 0);
  ASSERT_EQ(contents.stats.malformed_examples.size(), 2u);
  EXPECT_EQ(contents.stats.malformed_examples[1],
            path +
                ":3: FLASER: expected 12 fields after the message name for 2 readings, "
                "found 11");
  std::filesystem::remove(path);
}

TEST(EstimateLaserMountingTest, MedianOfLaserPoseInRobotFrame) {
  CarmenLogContents contents;
  for (double theta : {0.0, 1.0, -2.0}) {
    CarmenLaser laser;
    laser.robot_pose = Pose2(3.0, 4.0, theta);
    laser.laser_pose = Compose(laser.robot_pose, Pose2(-0.04, 0.0, 0.0));
    contents.lasers.push_back(laser);
  }
  const Pose2 mounting = EstimateLaserMounting(contents);
  EXPECT_NEAR(mounting.x(), -0.04, 1e-12);
  EXPECT_NEAR(mounting.y(), 0.0, 1e-12);
  EXPECT_NEAR(mounting.theta(), 0.0, 1e-12);
}

// The real logs of ../shared/data: the counts of `zcat FILE | grep -c '^FLASER'` and '^ODOM'
// (SOURCES.md), every line accounted for, the corrected ones recognised.
struct RealLog {
  const char* file;
  int64_t flaser;
  int64_t odom;
  int beams;
  bool corrected;
};

void PrintTo(const RealLog& log, std::ostream* os) { *os << log.file; }

class RealCarmenLogTest : public ::testing::TestWithParam<RealLog> {};

TEST_P(RealCarmenLogTest, CountsMatchTheFile) {
  const RealLog& log = GetParam();
  ANCHORMAP_REQUIRE_DATA(path, log.file);
  CarmenLogContents contents;
  const Status status = ReadCarmenLog(path, false, &contents);
  ASSERT_TRUE(status.ok()) << status.message();
  const CarmenLogStats& s = contents.stats;
  EXPECT_EQ(s.flaser_lines, log.flaser);
  EXPECT_EQ(s.odometry_lines, log.odom);
  EXPECT_EQ(s.robotlaser_lines, 0);
  EXPECT_EQ(s.malformed_lines, 0);
  EXPECT_EQ(s.scans_by_beam_count.at(log.beams), log.flaser);
  int64_t ignored = 0;
  for (const auto& [type, count] : s.ignored_by_type) ignored += count;
  EXPECT_EQ(s.lines, s.odometry_lines + s.flaser_lines + s.comment_or_blank_lines + ignored);
  EXPECT_EQ(contents.LooksCorrected(), log.corrected);
  EXPECT_EQ(s.reanchored_odometry_lines, log.corrected ? log.flaser : 0);
}

INSTANTIATE_TEST_SUITE_P(
    SharedData, RealCarmenLogTest,
    ::testing::Values(RealLog{"carmen/intel-corrected.log.gz", 910, 14541, 180, true},
                      RealLog{"carmen/aces-corrected.log.gz", 440, 7814, 180, true},
                      RealLog{"carmen/csail-corrected.log.gz", 406, 2394, 361, true},
                      RealLog{"carmen/freiburg-079-corrected.log.gz", 4791, 9725, 360, true},
                      RealLog{"benchmark/intel.clf.gz", 13631, 26915, 180, false},
                      RealLog{"benchmark/aces.clf.gz", 7374, 7375, 180, false},
                      RealLog{"benchmark/fr079.clf.gz", 4934, 8951, 360, false}));

}  // namespace
}  // namespace anchormap
