#include "common/io/map_file.h"
#include "tests/testing/scratch.h"

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

using ::anchormap::testing::ScratchPath;

GrayImage Gradient(int width, int height, int max_value) {
  GrayImage image;
  image.width = width;
  image.height = height;
  image.max_value = max_value;
  for (int i = 0; i < width * height; ++i)
    image.pixels.push_back(static_cast<uint16_t>((i * 37) % (max_value + 1)));
  return image;
}

TEST(MapFileTest, PgmRoundTrip8And16Bit) {
  for (int max_value : {255, 1000}) {
    const GrayImage image = Gradient(13, 7, max_value);
    const std::string path = ScratchPath("round_trip.pgm");
    ASSERT_TRUE(WritePgm(path, image).ok());
    // 8-bit: header "P5\n13 7\n255\n" (12 bytes) + 91 bytes; 16-bit: twice the data.
    EXPECT_EQ(std::filesystem::file_size(path), max_value > 255 ? 13u + 182u : 12u + 91u);
    GrayImage back;
    ASSERT_TRUE(ReadPgm(path, &back).ok());
    EXPECT_EQ(back.width, 13);
    EXPECT_EQ(back.height, 7);
    EXPECT_EQ(back.max_value, max_value);
    EXPECT_EQ(back.pixels, image.pixels);
  }
}

TEST(MapFileTest, ReadsAsciiPgmWithComments) {
  const std::string path = ScratchPath("ascii.pgm");
  std::ofstream(path) << "P2\n# a comment\n3 2 # trailing\n9\n0 1 2\n7 8 9\n";
  GrayImage image;
  ASSERT_TRUE(ReadPgm(path, &image).ok());
  EXPECT_EQ(image.width, 3);
  EXPECT_EQ(image.max_value, 9);
  EXPECT_EQ(image.at(2, 1), 9);
  EXPECT_EQ(image.at(0, 1), 7);
}

TEST(MapFileTest, RejectsBadPgm) {
  GrayImage image;
  const std::string path = ScratchPath("bad.pgm");
  std::ofstream(path) << "P6\n3 2\n255\n";
  EXPECT_FALSE(ReadPgm(path, &image).ok());
  std::ofstream(path, std::ios::trunc) << "P5\n3 2\n255\nab";  // 2 of 6 bytes
  const Status truncated = ReadPgm(path, &image);
  EXPECT_FALSE(truncated.ok());
  EXPECT_NE(truncated.message().find("truncated"), std::string::npos);
  std::ofstream(path, std::ios::trunc) << "P2\n2 1\n5\n3 6\n";  // pixel above max
  EXPECT_FALSE(ReadPgm(path, &image).ok());
  EXPECT_FALSE(ReadPgm(ScratchPath("absent.pgm"), &image).ok());
}

TEST(MapFileTest, YamlRoundTrip) {
  MapMetadata metadata;
  metadata.image = "map.pgm";
  metadata.resolution_m = 0.05;
  metadata.origin[0] = -12.5;
  metadata.origin[1] = 3.25;
  const std::string path = ScratchPath("map.yaml");
  ASSERT_TRUE(WriteMapYaml(path, metadata).ok());
  MapMetadata back;
  ASSERT_TRUE(ReadMapYaml(path, &back).ok());
  EXPECT_EQ(back.image, "map.pgm");
  EXPECT_DOUBLE_EQ(back.resolution_m, 0.05);
  EXPECT_DOUBLE_EQ(back.origin[0], -12.5);
  EXPECT_DOUBLE_EQ(back.origin[1], 3.25);
  EXPECT_EQ(back.negate, 0);
  EXPECT_DOUBLE_EQ(back.occupied_thresh, 0.65);
  EXPECT_DOUBLE_EQ(back.free_thresh, 0.196);
}

TEST(MapFileTest, YamlErrorsNameTheLine) {
  const std::string path = ScratchPath("bad.yaml");
  std::ofstream(path) << "image: m.pgm\nresolution: fast\n";
  MapMetadata unused;
  const Status status = ReadMapYaml(path, &unused);
  EXPECT_FALSE(status.ok());
  EXPECT_NE(status.message().find(":2:"), std::string::npos);
  std::ofstream(path, std::ios::trunc) << "resolution: 0.1\n";
  MapMetadata metadata;
  EXPECT_FALSE(ReadMapYaml(path, &metadata).ok());  // no image
}

TEST(MapFileTest, OccupancyToPgmValueFollowsMapSaver) {
  EXPECT_EQ(OccupancyToPgmValue(-1), 205);
  EXPECT_EQ(OccupancyToPgmValue(0), 254);
  EXPECT_EQ(OccupancyToPgmValue(19), 254);
  EXPECT_EQ(OccupancyToPgmValue(50), 205);
  EXPECT_EQ(OccupancyToPgmValue(65), 0);
  EXPECT_EQ(OccupancyToPgmValue(100), 0);
}

}  // namespace
}  // namespace anchormap
