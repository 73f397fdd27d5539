#include "tools/import_carmen/carmen_log.h"
#include "tests/testing/scratch.h"

#include <zlib.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

constexpr double kDeg = M_PI / 180.0;

using ::anchormap::testing::ScratchPath;

// A FLASER line of `n` ranges 1.0, 1.5, 2.0, ... followed by the given tail.
std::string Flaser(int n, const std::string& tail) {
  std::string line = "FLASER " + std::to_string(n);
  for (int i = 0; i < n; ++i) line += " " + std::to_string(1.0 + 0.5 * i);
  return line + " " + tail;
}

TEST(ParseCarmenLineTest, Odometry) {
  CarmenRecord record;
  ASSERT_TRUE(
      ParseCarmenLine("ODOM 1.5 -2.25 0.5 0.3 -0.1 0.0 976052857.337284 nohost 0.5\n", &record)
          .ok());
  EXPECT_EQ(record.kind, CarmenRecord::Kind::kOdometry);
  EXPECT_EQ(record.type, "ODOM");
  EXPECT_EQ(record.odometry.pose.x(), 1.5);
  EXPECT_EQ(record.odometry.pose.y(), -2.25);
  EXPECT_EQ(record.odometry.pose.theta(), 0.5);
  EXPECT_EQ(record.odometry.tv_mps, 0.3);
  EXPECT_EQ(record.odometry.rv_radps, -0.1);
  EXPECT_EQ(record.odometry.ipc_time_s, 976052857.337284);
  EXPECT_EQ(record.odometry.logger_time_s, 0.5);
}

TEST(ParseCarmenLineTest, FlaserWith180And360Beams) {
  CarmenRecord record;
  ASSERT_TRUE(
      ParseCarmenLine(Flaser(180, "0.6 -0.03 -0.35 0.5 -0.02 -0.3 32.9068 pippo 32.9"), &record)
          .ok());
  EXPECT_EQ(record.kind, CarmenRecord::Kind::kLaser);
  const CarmenLaser& laser = record.laser;
  EXPECT_EQ(laser.format, CarmenLaserFormat::kFlaser);
  ASSERT_EQ(laser.ranges_m.size(), 180u);
  EXPECT_EQ(laser.ranges_m[0], 1.0f);
  EXPECT_EQ(laser.ranges_m[179], 90.5f);
  EXPECT_DOUBLE_EQ(laser.start_angle_rad, -M_PI / 2);
  EXPECT_DOUBLE_EQ(laser.angular_resolution_rad, 1.0 * kDeg);
  EXPECT_EQ(laser.laser_pose.x(), 0.6);
  EXPECT_EQ(laser.laser_pose.theta(), -0.35);
  EXPECT_EQ(laser.robot_pose.x(), 0.5);
  EXPECT_EQ(laser.robot_pose.y(), -0.02);
  EXPECT_EQ(laser.robot_pose.theta(), -0.3);
  EXPECT_EQ(laser.ipc_time_s, 32.9068);
  EXPECT_EQ(laser.logger_time_s, 32.9);
  EXPECT_TRUE(laser.remissions.empty());

  ASSERT_TRUE(ParseCarmenLine(Flaser(360, "0 0 0 0 0 0 1 h 1"), &record).ok());
  EXPECT_DOUBLE_EQ(record.laser.angular_resolution_rad, 0.5 * kDeg);
  ASSERT_TRUE(ParseCarmenLine(Flaser(361, "0 0 0 0 0 0 1 h 1"), &record).ok());
  EXPECT_DOUBLE_EQ(record.laser.angular_resolution_rad, 0.5 * kDeg);
  // An unusual count spreads 180 degrees over n - 1 steps, as CARMEN does.
  ASSERT_TRUE(ParseCarmenLine(Flaser(5, "0 0 0 0 0 0 1 h 1"), &record).ok());
  EXPECT_DOUBLE_EQ(record.laser.angular_resolution_rad, 45.0 * kDeg);
}

TEST(ParseCarmenLineTest, RobotLaser1CarriesItsOwnGeometry) {
  // type start fov res max_range accuracy remission_mode | 3 ranges | 2 remissions |
  // laser pose | robot pose | tv rv forward side turn_axis | ipc host logger
  const std::string line =
      "ROBOTLASER1 0 -2.0 4.0 0.01 81.9 0.01 0 3 1.0 2.0 3.0 2 10 20 "
      "1.1 2.2 0.3 1.0 2.0 0.25 0.4 -0.2 0.5 0.3 1000000 1134863807.5 b21 2.5";
  CarmenRecord record;
  ASSERT_TRUE(ParseCarmenLine(line, &record).ok()) << ParseCarmenLine(line, &record).message();
  const CarmenLaser& laser = record.laser;
  EXPECT_EQ(laser.format, CarmenLaserFormat::kRobotLaser1);
  EXPECT_EQ(laser.start_angle_rad, -2.0);
  EXPECT_EQ(laser.fov_rad, 4.0);
  EXPECT_EQ(laser.angular_resolution_rad, 0.01);
  EXPECT_EQ(laser.max_range_m, 81.9);
  EXPECT_EQ(laser.ranges_m, (std::vector<float>{1.0f, 2.0f, 3.0f}));
  EXPECT_EQ(laser.remissions, (std::vector<float>{10.0f, 20.0f}));
  EXPECT_EQ(laser.laser_pose.x(), 1.1);
  EXPECT_EQ(laser.laser_pose.theta(), 0.3);
  EXPECT_EQ(laser.robot_pose.theta(), 0.25);
  EXPECT_EQ(laser.tv_mps, 0.4);
  EXPECT_EQ(laser.rv_radps, -0.2);
  EXPECT_EQ(laser.ipc_time_s, 1134863807.5);
  EXPECT_EQ(laser.logger_time_s, 2.5);
}

TEST(ParseCarmenLineTest, IgnoredLines) {
  CarmenRecord record;
  for (const char* line : {"PARAM robot_length 0.54 1134863807.659124 b21 1134863807.659121",
                           "RAWLASER1 0 -1.57 3.14 0.0174 81.9 0.01 0 1 2.0 0 1.0 h 1.0",
                           "NEFF 27.6666 0 pippo 0", "RLASER 1 2.0 0 0 0 0 0 0 1 h 1"}) {
    ASSERT_TRUE(ParseCarmenLine(line, &record).ok()) << line;
    EXPECT_EQ(record.kind, CarmenRecord::Kind::kIgnored) << line;
  }
  EXPECT_EQ(record.type, "RLASER");
  ASSERT_TRUE(ParseCarmenLine("# message formats defined: PARAM SYNC ODOM", &record).ok());
  EXPECT_EQ(record.type, "#");
  ASSERT_TRUE(ParseCarmenLine("   \r", &record).ok());
  EXPECT_EQ(record.type, "");
  EXPECT_EQ(record.kind, CarmenRecord::Kind::kIgnored);
}

TEST(ParseCarmenLineTest, MalformedLinesSayWhichFieldAndWhy) {
  const auto error = [](const std::string& line) {
    CarmenRecord record;
    return ParseCarmenLine(line, &record).message();
  };
  EXPECT_EQ(error("ODOM 1 2 3 0 0 0 5.0 host"),
            "ODOM: expected 9 fields after the message name (x y theta tv rv accel "
            "ipc_timestamp host logger_timestamp), found 8");
  EXPECT_EQ(error("ODOM 1 2 abc 0 0 0 5.0 host 5.0"), "ODOM: theta 'abc' is not a finite number");
  EXPECT_EQ(error("ODOM 1 2 3 0 0 0 nan host 5.0"),
            "ODOM: ipc_timestamp 'nan' is not a finite number");
  EXPECT_EQ(error("FLASER"), "FLASER: missing num_readings");
  EXPECT_EQ(error("FLASER 2.5 1 2"), "FLASER: num_readings '2.5' is not an integer");
  EXPECT_EQ(error("FLASER 0 0 0 0 0 0 0 1 h 1"),
            "FLASER: num_readings 0 is out of range [1, 100000]");
  EXPECT_EQ(error("FLASER 3 1 2 0 0 0 0 0 0 1 h 1"),
            "FLASER: expected 13 fields after the message name for 3 readings, found 12");
  EXPECT_EQ(error("FLASER 3 1 x 3 0 0 0 0 0 0 1 h 1"),
            "FLASER: range 2 of 3 'x' is not a finite number");
  EXPECT_EQ(error("FLASER 3 1 -2 3 0 0 0 0 0 0 1 h 1"), "FLASER: range 2 of 3 is negative (-2)");
  EXPECT_EQ(error("FLASER 1 1 0 0 0 0 y 0 1 h 1"), "FLASER: odom_y 'y' is not a finite number");
  EXPECT_EQ(error("FLASER 1 1 0 0 0 0 0 0 1 h 1e999"),
            "FLASER: logger_timestamp '1e999' is not a finite number");
  EXPECT_EQ(error("ROBOTLASER1 0 -1.5 3.1 0.01 80"),
            "ROBOTLASER1: expected at least 24 fields after the message name, found 5");
  EXPECT_EQ(error("ROBOTLASER1 0 -1.5 3.1 0.01 80 0.01 0 3 1 2"),
            "ROBOTLASER1: expected at least 26 fields after the message name for 3 readings, "
            "found 10");
  // 7 + n(1) + 1 range + m(1) + 1 remission + 14 = 25 fields; one extra field:
  EXPECT_EQ(error("ROBOTLASER1 0 -1.5 3.1 0.01 80 0.01 0 1 1 1 5 0 0 0 0 0 0 0 0 0 0 0 0 1 h 1"),
            "ROBOTLASER1: expected 25 fields after the message name for 1 readings and 1 "
            "remissions, found 26");
  EXPECT_EQ(error("ROBOTLASER1 0 -1.5 3.1 0 80 0.01 0 2 1 1 0 0 0 0 0 0 0 0 0 0 0 0 1 h 1"),
            "ROBOTLASER1: angular_resolution is 0");
  EXPECT_EQ(error("3.14 2.72"), "line does not start with a message name ('3.14')");
  EXPECT_EQ(error("odom 1 2 3"), "line does not start with a message name ('odom')");
}

// Writes `text` to `path`, gzip-compressed when `gzip` is true.
void WriteFile(const std::string& path, const std::string& text, bool gzip) {
  if (!gzip) {
    std::ofstream(path, std::ios::binary) << text;
    return;
  }
  gzFile file = gzopen(path.c_str(), "wb");
  ASSERT_NE(file, nullptr);
  ASSERT_EQ(gzwrite(file, text.data(), static_cast<unsigned>(text.size())),
            static_cast<int>(text.size()));
  gzclose(file);
}

std::vector<std::string> ReadAllLines(const std::string& path, Status* status) {
  CarmenLogReader reader;
  *status = reader.Open(path);
  std::vector<std::string> lines;
  std::string line;
  while (reader.ReadLine(&line)) {
    lines.push_back(line);
    EXPECT_EQ(reader.line_number(), static_cast<int64_t>(lines.size()));
  }
  if (status->ok()) *status = reader.status();
  return lines;
}

TEST(CarmenLogReaderTest, PlainAndGzipGiveTheSameLines) {
  // A long line (longer than the reader's 64 KiB chunk), CRLF, and no final newline.
  const std::string long_line = Flaser(20000, "0 0 0 0 0 0 1 h 1");
  const std::string text = "# comment\r\nODOM 0 0 0 0 0 0 1 h 1\n" + long_line + "\n\nlast";
  for (bool gzip : {false, true}) {
    const std::string path = ScratchPath(gzip ? "am_carmen_reader.log.gz" : "am_carmen_reader.log");
    WriteFile(path, text, gzip);
    Status status = Status::Ok();
    const std::vector<std::string> lines = ReadAllLines(path, &status);
    EXPECT_TRUE(status.ok()) << status.message();
    ASSERT_EQ(lines.size(), 5u) << "gzip " << gzip;
    EXPECT_EQ(lines[0], "# comment");
    EXPECT_EQ(lines[1], "ODOM 0 0 0 0 0 0 1 h 1");
    EXPECT_EQ(lines[2], long_line);
    EXPECT_EQ(lines[3], "");
    EXPECT_EQ(lines[4], "last");
    std::filesystem::remove(path);
  }
}

TEST(CarmenLogReaderTest, NulBytesStayInsideTheirLine) {
  const std::string path = ScratchPath("am_carmen_nul.log");
  WriteFile(path, std::string("ODOM 0 0\0 0 0 0 0 1 h 1\nODOM 0 0 0 0 0 0 2 h 2\n", 47), false);
  Status status = Status::Ok();
  const std::vector<std::string> lines = ReadAllLines(path, &status);
  ASSERT_EQ(lines.size(), 2u);
  EXPECT_EQ(lines[0].size(), 23u);
  EXPECT_EQ(lines[1], "ODOM 0 0 0 0 0 0 2 h 2");
  CarmenRecord record;
  EXPECT_EQ(ParseCarmenLine(lines[0], &record).message(),
            "ODOM: y '0\\x00' is not a finite number");
  std::filesystem::remove(path);
}

TEST(CarmenLogReaderTest, TruncatedGzipIsAReadErrorNotASilentEnd) {
  std::string text;
  for (int i = 0; i < 20000; ++i) text += "ODOM " + std::to_string(i) + " 0 0 0 0 0 1 h 1\n";
  const std::string path = ScratchPath("am_carmen_truncated.log.gz");
  WriteFile(path, text, true);
  std::filesystem::resize_file(path, std::filesystem::file_size(path) / 2);
  Status status = Status::Ok();
  const std::vector<std::string> lines = ReadAllLines(path, &status);
  EXPECT_FALSE(status.ok());
  EXPECT_NE(status.message().find(path + ":"), std::string::npos) << status.message();
  EXPECT_NE(status.message().find("read error"), std::string::npos) << status.message();
  EXPECT_LT(lines.size(), 20000u);
  std::filesystem::remove(path);

  CarmenLogReader reader;
  const Status missing = reader.Open("/nonexistent/x.log");
  EXPECT_EQ(missing.message(),
            "cannot open CARMEN log '/nonexistent/x.log': No such file or directory");
}

}  // namespace
}  // namespace anchormap
