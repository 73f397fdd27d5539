// anchormap-import-carmen as a process: exit codes, messages, and the real logs end to end.

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>

#include <unistd.h>

#include <gtest/gtest.h>

#include "bot_core/pose_t.hpp"
#include "common/bus/lcm_log.h"
#include "tests/testing/data_path.h"
#include "tests/testing/file_contents.h"
#include "tests/testing/scratch.h"

namespace anchormap {
namespace {

namespace fs = std::filesystem;

struct RunResult {
  int exit_code = -1;
  std::string out;
  std::string err;
};

using ::anchormap::testing::ScratchPath;

RunResult RunImporter(const std::string& arguments) {
  const std::string out = ScratchPath("am_import_cli.out");
  const std::string err = ScratchPath("am_import_cli.err");
  const std::string command = std::string(ANCHORMAP_BINARY_DIR) + "/bin/anchormap-import-carmen " +
                              arguments + " >" + out + " 2>" + err;
  const int status = std::system(command.c_str());
  RunResult result;
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  result.out = ::anchormap::testing::FileContents(out);
  result.err = ::anchormap::testing::FileContents(err);
  fs::remove(out);
  fs::remove(err);
  return result;
}

std::map<std::string, int64_t> CountChannels(const std::string& lcm_log) {
  std::map<std::string, int64_t> counts;
  LcmLogReader reader;
  EXPECT_TRUE(reader.Open(lcm_log).ok());
  int64_t last_utime = INT64_MIN;
  while (auto event = reader.Next()) {
    ++counts[event->channel];
    EXPECT_GE(event->utime, last_utime) << "events not in time order";
    last_utime = event->utime;
  }
  return counts;
}

TEST(ImportCarmenCliTest, HelpAndBadFlags) {
  const RunResult help = RunImporter("--help");
  EXPECT_EQ(help.exit_code, 0);
  EXPECT_NE(help.out.find("--split"), std::string::npos);
  EXPECT_EQ(RunImporter("--no-such-flag").exit_code, 2);
  EXPECT_EQ(RunImporter("in.log").exit_code, 2);  // no --output
  const RunResult bad_split = RunImporter("in.log --output x.lcmlog --split 0");
  EXPECT_EQ(bad_split.exit_code, 2);
  EXPECT_NE(bad_split.err.find("split: 0 is not in [1, 100]"), std::string::npos) << bad_split.err;
  EXPECT_EQ(RunImporter("in.log --output x.lcmlog --odometry-source wheels").exit_code, 2);
  EXPECT_EQ(RunImporter("in.log --output x.lcmlog --split two").exit_code, 2);
  EXPECT_EQ(RunImporter("/nonexistent/in.log --output x.lcmlog").exit_code, 1);
}

TEST(ImportCarmenCliTest, MalformedLineFailsWithFileAndLineUnlessLenient) {
  const std::string input = ScratchPath("am_cli_malformed.log");
  const std::string output = ScratchPath("am_cli_malformed.lcmlog");
  std::ofstream(input) << "ODOM 0 0 0 0 0 0 1.0 h 1.0\n"
                          "FLASER 2 1.0 2.0 0 0 0 0 0 0 1.0 h 1.0\n"
                          "FLASER 2 1.0 0 0 0 0 0 0 1.5 h 1.5\n"
                          "ODOM 0.5 0 0 0 0 0 2.0 h 2.0\n";
  const RunResult strict = RunImporter(input + " --output " + output);
  EXPECT_EQ(strict.exit_code, 1);
  EXPECT_EQ(strict.err, input +
                            ":3: FLASER: expected 12 fields after the message name for 2 "
                            "readings, found 11\n");
  const RunResult lenient = RunImporter(input + " --output " + output + " --lenient");
  EXPECT_EQ(lenient.exit_code, 0) << lenient.err;
  EXPECT_NE(lenient.out.find("malformed 1"), std::string::npos) << lenient.out;
  const auto counts = CountChannels(output);
  EXPECT_EQ(counts.at("R1_ODOMETRY"), 2);
  EXPECT_EQ(counts.at("R1_LASER"), 1);
  EXPECT_EQ(counts.at("R1_REFERENCE"), 1);
  fs::remove(input);
  fs::remove(output);
}

struct RealLog {
  const char* file;
  int64_t flaser;
  int64_t odom;  // odometry messages: the ODOM lines, or the laser lines when stamps step back
  int64_t repaired = 0;  // laser lines stamped at or before the line before them
};
void PrintTo(const RealLog& log, std::ostream* os) { *os << log.file; }

class ImportRealLogTest : public ::testing::TestWithParam<RealLog> {};

// Every scan and every odometry line of the file becomes one LCM message.
TEST_P(ImportRealLogTest, MessageCountsEqualTheFile) {
  ANCHORMAP_REQUIRE_DATA(input, GetParam().file);
  const std::string output = ScratchPath("am_cli_real.lcmlog");
  const RunResult result = RunImporter(input + " --output " + output + " --robot R3");
  ASSERT_EQ(result.exit_code, 0) << result.err;
  const auto counts = CountChannels(output);
  EXPECT_EQ(counts.size(), GetParam().repaired > 0 ? 5u : 4u);
  if (GetParam().repaired > 0) {
    EXPECT_EQ(counts.at("R3_TIME_REPAIR"), GetParam().repaired);
  }
  EXPECT_EQ(counts.at("R3_LASER_MOUNT"), 1);  // the laser's mounting pose, for the agent
  EXPECT_EQ(counts.at("R3_LASER"), GetParam().flaser);
  EXPECT_EQ(counts.at("R3_REFERENCE"), GetParam().flaser);
  EXPECT_EQ(counts.at("R3_ODOMETRY"), GetParam().odom);
  fs::remove(output);
}

INSTANTIATE_TEST_SUITE_P(SharedData, ImportRealLogTest,
                         ::testing::Values(RealLog{"carmen/intel-corrected.log.gz", 910, 910, 4},
                                           RealLog{"carmen/aces-corrected.log.gz", 440, 7814},
                                           // Stamps printed with 6 digits (10 s steps).
                                           RealLog{"carmen/csail-corrected.log.gz", 406, 406, 404},
                                           RealLog{"carmen/freiburg-079-corrected.log.gz", 4791,
                                                   9725},
                                           RealLog{"benchmark/intel.clf.gz", 13631, 13631, 1612},
                                           RealLog{"benchmark/aces.clf.gz", 7374, 7375},
                                           RealLog{"benchmark/fr079.clf.gz", 4934, 8951}));

TEST(ImportCarmenCliTest, SplitOfARealLogGivesRobotsStartingAtTheOrigin) {
  ANCHORMAP_REQUIRE_DATA(input, "benchmark/aces.clf.gz");
  const std::string output = ScratchPath("am_cli_split.lcmlog");
  const RunResult result = RunImporter(input + " --output " + output + " --split 3 --gap-s 20");
  ASSERT_EQ(result.exit_code, 0) << result.err;
  LcmLogReader reader;
  ASSERT_TRUE(reader.Open(output).ok());
  std::map<std::string, bot_core::pose_t> first_odometry;
  std::map<std::string, int64_t> counts;
  int64_t last_utime[3] = {0, 0, 0};
  while (auto event = reader.Next()) {
    ++counts[event->channel];
    if (event->channel.size() > 9 && event->channel.substr(2) == "_ODOMETRY") {
      const int robot = event->channel[1] - '1';
      ASSERT_TRUE(robot >= 0 && robot < 3) << event->channel;
      last_utime[robot] = event->utime;
      if (!first_odometry.count(event->channel)) {
        first_odometry[event->channel] = *DecodeAs<bot_core::pose_t>(*event);
      }
    }
  }
  ASSERT_EQ(first_odometry.size(), 3u);
  for (const auto& [channel, pose] : first_odometry) {
    EXPECT_NEAR(std::hypot(pose.pos[0], pose.pos[1]), 0.0, 1e-12) << channel;
    EXPECT_NEAR(pose.orientation[0], 1.0, 1e-12) << channel;
  }
  // Cuts at 70.18 + k * 1365.72 / 3 = 525.42 and 980.66 s; 20 s gaps drop 179 scans
  // (awk '$1=="FLASER" && |ipc_timestamp - cut| < 10' on the file) and 179 ODOM lines.
  EXPECT_EQ(counts["R1_LASER"], 2507);
  EXPECT_EQ(counts["R2_LASER"], 1950);
  EXPECT_EQ(counts["R3_LASER"], 2738);
  EXPECT_EQ(counts["R1_ODOMETRY"], 2508);
  EXPECT_EQ(counts["R2_ODOMETRY"], 1950);
  EXPECT_EQ(counts["R3_ODOMETRY"], 2738);
  EXPECT_EQ(2507 + 1950 + 2738 + 179, 7374);
  EXPECT_EQ(counts["R2_REFERENCE"], 1950);
  EXPECT_LE(last_utime[0] + 10000000, first_odometry["R2_ODOMETRY"].utime);
  EXPECT_LE(last_utime[1] + 10000000, first_odometry["R3_ODOMETRY"].utime);
  EXPECT_NE(result.out.find("split        3 pieces, gap 20.000 s"), std::string::npos)
      << result.out;
  fs::remove(output);
}

TEST(ImportCarmenCliTest, SimultaneousPiecesStartTogetherWithShiftAndMountRecorded) {
  ANCHORMAP_REQUIRE_DATA(input, "benchmark/fr079.clf.gz");
  const std::string output = ScratchPath("am_cli_simultaneous.lcmlog");
  const RunResult result = RunImporter(input + " --output " + output + " --split 2 --simultaneous");
  ASSERT_EQ(result.exit_code, 0) << result.err;
  LcmLogReader reader;
  ASSERT_TRUE(reader.Open(output).ok());
  std::map<std::string, int64_t> first_utime;
  std::map<std::string, bot_core::pose_t> parameters;
  while (auto event = reader.Next()) {
    if (!first_utime.count(event->channel)) first_utime[event->channel] = event->utime;
    if (event->channel.find("_MOUNT") != std::string::npos ||
        event->channel.find("_CLOCK_SHIFT") != std::string::npos) {
      parameters[event->channel] = *DecodeAs<bot_core::pose_t>(*event);
    }
  }
  // fr079's laser sits 4 cm behind the robot's centre (the importer's median estimate).
  for (const char* robot : {"R1", "R2"}) {
    const std::string name = robot;
    ASSERT_TRUE(parameters.count(name + "_LASER_MOUNT")) << robot;
    EXPECT_NEAR(parameters[name + "_LASER_MOUNT"].pos[0], -0.04, 1e-3);
    ASSERT_TRUE(parameters.count(name + "_CLOCK_SHIFT")) << robot;
  }
  // The second piece moved back to start with the first: by half the log (1061.7 s) plus half
  // the 2 % gap, within a scan period.
  EXPECT_EQ(parameters["R1_CLOCK_SHIFT"].utime, 0);
  EXPECT_NEAR(1e-6 * static_cast<double>(parameters["R2_CLOCK_SHIFT"].utime),
              -(0.5 + 0.01) * 1061.699, 0.5);
  EXPECT_NEAR(1e-6 * static_cast<double>(first_utime["R1_ODOMETRY"] - first_utime["R2_ODOMETRY"]),
              0.0, 0.5);
  EXPECT_NE(result.out.find("shifted by"), std::string::npos) << result.out;
  fs::remove(output);
}

}  // namespace
}  // namespace anchormap
