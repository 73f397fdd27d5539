#include "tools/render/map_export.h"
#include "tests/testing/scratch.h"

#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

namespace anchormap::render {
namespace {

using ::anchormap::testing::ScratchPath;

// A PGM decoder independent of common/io/map_file: header by stream extraction, then the
// raw bytes.
bool ReadBinaryPgm(const std::string& path, int* width, int* height, std::vector<uint8_t>* pixels) {
  std::ifstream in(path, std::ios::binary);
  std::string magic;
  int max_value = 0;
  if (!(in >> magic >> *width >> *height >> max_value) || magic != "P5" || max_value != 255)
    return false;
  in.get();  // the single whitespace before the data
  pixels->resize(static_cast<size_t>(*width) * *height);
  in.read(reinterpret_cast<char*>(pixels->data()), static_cast<std::streamsize>(pixels->size()));
  return in.gcount() == static_cast<std::streamsize>(pixels->size()) && in.peek() == EOF;
}

OccupancyRaster TestRaster() {
  OccupancyRaster raster;
  raster.resolution_m = 0.25;
  raster.origin = Eigen::Vector2d(-3.0, 1.5);
  raster.width = 5;
  raster.height = 3;
  raster.cells = {100, 0,  0,  -1, 30,    // bottom row
                  0,   0,  80, 0,  0,     //
                  -1,  -1, 0,  0,  100};  // top row
  return raster;
}

TEST(MapExportTest, PgmPixelsFollowMapSaverWithTheTopRowFirst) {
  const std::string pgm = ScratchPath("export.pgm");
  const std::string yaml = YamlPathFor(pgm);
  EXPECT_EQ(std::filesystem::path(yaml).filename(), "export.yaml");
  ASSERT_TRUE(WriteMapServerFiles(TestRaster(), pgm, yaml).ok());
  int width = 0;
  int height = 0;
  std::vector<uint8_t> pixels;
  ASSERT_TRUE(ReadBinaryPgm(pgm, &width, &height, &pixels));
  EXPECT_EQ(width, 5);
  EXPECT_EQ(height, 3);
  const std::vector<uint8_t> expected = {205, 205, 254, 254, 0,     // top row first
                                         254, 254, 0,   254, 254,   //
                                         0,   254, 254, 205, 205};  // 30 % is neither
  EXPECT_EQ(pixels, expected);
}

TEST(MapExportTest, YamlHasTheMapServerFields) {
  const std::string pgm = ScratchPath("fields.pgm");
  const std::string yaml = ScratchPath("fields.yaml");
  ASSERT_TRUE(WriteMapServerFiles(TestRaster(), pgm, yaml).ok());
  std::ifstream in(yaml);
  std::stringstream text;
  text << in.rdbuf();
  const std::string s = text.str();
  EXPECT_NE(s.find("image: fields.pgm\n"), std::string::npos) << s;
  EXPECT_NE(s.find("resolution: 0.250000\n"), std::string::npos) << s;
  EXPECT_NE(s.find("origin: [-3.000000, 1.500000, 0.000000]\n"), std::string::npos) << s;
  EXPECT_NE(s.find("negate: 0\n"), std::string::npos) << s;
  EXPECT_NE(s.find("occupied_thresh: 0.650\n"), std::string::npos) << s;
  EXPECT_NE(s.find("free_thresh: 0.196\n"), std::string::npos) << s;
}

TEST(MapExportTest, YamlInAnotherFolderNamesTheImageAbsolutely) {
  const std::filesystem::path dir = ::anchormap::testing::ScratchDir() / "export_sub";
  std::filesystem::create_directories(dir);
  const std::string pgm = ScratchPath("elsewhere.pgm");
  const std::string yaml = (dir / "elsewhere.yaml").string();
  ASSERT_TRUE(WriteMapServerFiles(TestRaster(), pgm, yaml).ok());
  std::ifstream in(yaml);
  std::string first_line;
  std::getline(in, first_line);
  EXPECT_EQ(first_line, "image: " + std::filesystem::absolute(pgm).string());
}

TEST(MapExportTest, EmptyRasterIsAnError) {
  EXPECT_FALSE(
      WriteMapServerFiles(OccupancyRaster{}, ScratchPath("e.pgm"), ScratchPath("e.yaml")).ok());
}

}  // namespace
}  // namespace anchormap::render
