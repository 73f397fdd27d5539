#include "tools/render/uncertainty_plot.h"

#include <cmath>
#include <filesystem>

#include <gtest/gtest.h>

#include "tests/testing/scratch.h"
#include "tools/render/testing_helpers.h"

namespace anchormap::render {
namespace {

using ::anchormap::testing::ScratchPath;

bool NearColor(const Rgb& a, const Rgb& b, int tolerance) {
  return std::abs(a.r - b.r) <= tolerance && std::abs(a.g - b.g) <= tolerance &&
         std::abs(a.b - b.b) <= tolerance;
}

TEST(UncertaintyPlotTest, OneLinePerAnchorAtItsValues) {
  const std::string log = ScratchPath("plot.lcmlog");
  ASSERT_TRUE(testing::WriteTestServerLog(log).ok());
  ServerOutput output;
  ASSERT_TRUE(ReadServerOutput(log, ChannelNames{}, &output).ok());
  const ColorAssignment colors({{"R1", 11}, {"R2", 12}});
  const std::string png = ScratchPath("plot.png");
  PlotFrame frame;
  UncertaintyPlotOptions options;
  ASSERT_TRUE(RenderUncertaintyPlot(output.anchor_samples, colors, options, png, &frame).ok());
  testing::DecodedPng image;
  ASSERT_TRUE(testing::DecodePng(png, &image));
  EXPECT_EQ(image.width, 960);
  EXPECT_EQ(image.height, 540);
  EXPECT_EQ(frame.x_min, 1.0);
  EXPECT_EQ(frame.x_max, 9.0);
  EXPECT_NEAR(frame.y_max, 2.0 * 1.08, 1e-12);
  // R2's line passes (5, 1.2) (sigma 2.0 - 0.2 * 4); R1's lies on zero.
  const Eigen::Vector2d r2 = frame.ToPixel(5.0, 1.2);
  EXPECT_TRUE(NearColor(image.at(static_cast<int>(r2.x()), static_cast<int>(r2.y())),
                        TrajectoryColor(1), 10));
  const Eigen::Vector2d r1 = frame.ToPixel(5.0, 0.0);
  EXPECT_TRUE(NearColor(image.at(static_cast<int>(r1.x()), static_cast<int>(r1.y()) - 1),
                        TrajectoryColor(0), 40));
  // Far from both lines: background white.
  const Eigen::Vector2d empty = frame.ToPixel(2.0, 0.7);
  EXPECT_EQ(image.at(static_cast<int>(empty.x()) + 3, static_cast<int>(empty.y()) + 3),
            (Rgb{255, 255, 255}));
}

TEST(UncertaintyPlotTest, EmptyPlotStillWritesAPng) {
  const std::string png = ScratchPath("empty_plot.png");
  ASSERT_TRUE(RenderUncertaintyPlot({}, ColorAssignment({}), UncertaintyPlotOptions{}, png).ok());
  testing::DecodedPng image;
  EXPECT_TRUE(testing::DecodePng(png, &image));
}

TEST(UncertaintyPlotTest, NiceTicks) {
  EXPECT_EQ(NiceTicks(0.0, 2.16, 6), (std::vector<double>{0.0, 0.5, 1.0, 1.5, 2.0}));
  EXPECT_EQ(NiceTicks(1.0, 9.0, 8), (std::vector<double>{1, 2, 3, 4, 5, 6, 7, 8, 9}));
  EXPECT_EQ(NiceTicks(0.0, 1000.0, 5), (std::vector<double>{0, 200, 400, 600, 800, 1000}));
}

}  // namespace
}  // namespace anchormap::render
