#include "tools/render/map_png.h"

#include <cmath>
#include <filesystem>

#include <gtest/gtest.h>

#include "tests/testing/scratch.h"
#include "tools/render/testing_helpers.h"

namespace anchormap::render {
namespace {

using ::anchormap::testing::ScratchPath;

struct Rendered {
  ServerOutput output;
  OccupancyRaster raster;
  MapViewport viewport;
  testing::DecodedPng png;
};

Rendered RenderTestLog(bool with_grid, const MapPngOptions& options = MapPngOptions{}) {
  Rendered r;
  const std::string log = ScratchPath("map_png_test.lcmlog");
  EXPECT_TRUE(testing::WriteTestServerLog(log).ok());
  EXPECT_TRUE(ReadServerOutput(log, ChannelNames{}, &r.output).ok());
  if (with_grid) r.raster = AssembleGrid(r.output.grid);
  const std::string png = ScratchPath(with_grid ? "map_grid.png" : "map_nogrid.png");
  const ColorAssignment colors({{"R1", 11}, {"R2", 12}, {"R3", 13}});
  EXPECT_TRUE(RenderMapPng(&*r.output.map, r.raster, colors, options, png, &r.viewport).ok());
  EXPECT_TRUE(testing::DecodePng(png, &r.png));  // decoded by libpng, not cairo
  return r;
}

Rgb PixelAt(const Rendered& r, const Eigen::Vector2d& world) {
  const Eigen::Vector2d p = r.viewport.ToPixel(world);
  return r.png.at(static_cast<int>(std::floor(p.x())), static_cast<int>(std::floor(p.y())));
}

TEST(MapPngTest, SizeTrajectoryColoursAndGrid) {
  const Rendered r = RenderTestLog(true);
  EXPECT_EQ(r.png.width, r.viewport.width_px);
  EXPECT_EQ(r.png.height, r.viewport.height_px);
  // Content (grid and poses) [0, 10] x [0, 10] plus 2 m margins: 14 x 14 m, 1400 px.
  EXPECT_NEAR(r.viewport.pixels_per_m, 100.0, 1e-9);
  EXPECT_EQ(r.png.width, 1400);
  // On R1's path (y = 2) and R2's (x = 10), away from the encounter line: their colours.
  EXPECT_EQ(PixelAt(r, {2.0, 2.0}), TrajectoryColor(0));
  EXPECT_EQ(PixelAt(r, {10.0, 5.0}), TrajectoryColor(1));
  // Grid: the occupied column of tile (0, 0) at x in [0, 0.5] is black, free cells white,
  // and outside the grid (x > 10) the white background.
  EXPECT_EQ(PixelAt(r, {0.25, 4.0}), (Rgb{0, 0, 0}));
  EXPECT_EQ(PixelAt(r, {7.0, 7.0}), (Rgb{255, 255, 255}));
  EXPECT_EQ(PixelAt(r, {5.25, 7.0}), (Rgb{0, 0, 0}));  // tile (1, 1)'s occupied column
  // The encounter line between (8, 2) and (10, 2) is dark (anti-aliased over two rows).
  const Rgb on_link = PixelAt(r, {9.0, 2.0});
  EXPECT_LT(on_link.r + on_link.g + on_link.b, 3 * 160);
}

TEST(MapPngTest, LongTitleFitsTheImage) {
  MapPngOptions options;
  options.title = std::string(60, 'W');  // with the counts ~2000 px at the usual size
  const Rendered r = RenderTestLog(true, options);
  // The title band's background (245, 245, 245) is untouched in the last 8 px columns, and
  // the title's ink reaches the band's second half (it was set smaller, not dropped).
  int inked_right_half = 0;
  for (int y = 0; y < r.viewport.header_px; ++y) {
    for (int x = r.png.width - 8; x < r.png.width; ++x) {
      EXPECT_EQ(r.png.at(x, y), (Rgb{245, 245, 245})) << x << "," << y;
    }
    for (int x = r.png.width / 2; x < r.png.width - 8; ++x) {
      if (r.png.at(x, y).r < 128) ++inked_right_half;
    }
  }
  EXPECT_GT(inked_right_half, 100);
}

TEST(MapPngTest, WithoutGridOnlyTrajectories) {
  const Rendered r = RenderTestLog(false);
  EXPECT_EQ(PixelAt(r, {2.0, 2.0}), TrajectoryColor(0));
  EXPECT_EQ(PixelAt(r, {0.25, 4.0}), (Rgb{255, 255, 255}));  // no grid drawn
  // Viewport: the poses [0, 10] x [0, 8] plus margins.
  EXPECT_NEAR(r.viewport.world_max.y(), 10.0, 1e-9);
}

TEST(MapPngTest, ExplicitScale) {
  MapPngOptions options;
  options.pixels_per_m = 20.0;
  const Rendered r = RenderTestLog(true, options);
  EXPECT_EQ(r.png.width, 320);  // 14 m * 20 = 280 px, widened to the minimum 320
  EXPECT_EQ(r.png.height, r.viewport.header_px + 14 * 20);
  EXPECT_EQ(PixelAt(r, {2.0, 2.0}), TrajectoryColor(0));
}

// The legend names the three constraint kinds, each beside a line in the colour the map
// draws it in (direct dark, scan encounters magenta, loop closures grey).
TEST(MapPngTest, LegendShowsEachConstraintKindInItsColour) {
  ServerOutput output;
  const std::string log = ScratchPath("map_png_kinds.lcmlog");
  ASSERT_TRUE(testing::WriteTestServerLog(log).ok());
  ASSERT_TRUE(ReadServerOutput(log, ChannelNames{}, &output).ok());
  MergedMap map = *output.map;
  ASSERT_FALSE(map.encounters.empty());
  EncounterLink scan = map.encounters.front();
  scan.kind = ConstraintKind::kScanEncounter;
  EncounterLink loop = scan;
  loop.kind = ConstraintKind::kLoopClosure;
  loop.b = loop.a;
  loop.index_b = loop.index_a + 1;
  map.encounters.push_back(scan);
  map.encounters.push_back(loop);
  const std::string png_path = ScratchPath("map_kinds.png");
  const ColorAssignment colors({{"R1", 11}, {"R2", 12}, {"R3", 13}});
  MapViewport viewport;
  ASSERT_TRUE(
      RenderMapPng(&map, OccupancyRaster{}, colors, MapPngOptions{}, png_path, &viewport).ok());
  testing::DecodedPng png;
  ASSERT_TRUE(testing::DecodePng(png_path, &png));
  // The legend's line column (x = 28 px), from the title band down: the trajectory rows,
  // then one row per kind. Each kind's colour is there exactly (its line's core).
  auto found = [&](const Rgb& color) {
    for (int y = viewport.header_px; y < viewport.header_px + 200; ++y) {
      if (png.at(28, y) == color) return true;
    }
    return false;
  };
  EXPECT_TRUE(found(Rgb{40, 40, 40}));     // direct encounters
  EXPECT_TRUE(found(Rgb{220, 0, 170}));    // scan encounters
  EXPECT_TRUE(found(Rgb{150, 150, 150}));  // loop closures
  // Without links drawn, no kind rows.
  MapPngOptions no_links;
  no_links.draw_encounters = false;
  ASSERT_TRUE(RenderMapPng(&map, OccupancyRaster{}, colors, no_links, png_path, &viewport).ok());
  ASSERT_TRUE(testing::DecodePng(png_path, &png));
  EXPECT_FALSE(found(Rgb{220, 0, 170}));
  EXPECT_FALSE(found(Rgb{150, 150, 150}));
}

TEST(MapPngTest, OccupancyGrayLevels) {
  EXPECT_EQ(OccupancyGray(-1), 205);
  EXPECT_EQ(OccupancyGray(0), 255);
  EXPECT_EQ(OccupancyGray(100), 0);
  EXPECT_EQ(OccupancyGray(19), 255);
  EXPECT_EQ(OccupancyGray(50), 84);  // 255 * (65 - 50) / (65 - 19.6)
  EXPECT_EQ(OccupancyGray(65), 0);
}

}  // namespace
}  // namespace anchormap::render
