#pragma once
// The anchors' positional uncertainty over the solver updates as a line plot (thesis Fig.
// 4-11): x = update number, y = sqrt(sigma_x^2 + sigma_y^2) of each anchor in metres, one
// line per anchor in its trajectory's colour, with axes, ticks, labels and a legend.

#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/util/status.h"
#include "tools/render/colors.h"
#include "tools/render/server_output.h"

namespace anchormap::render {

struct UncertaintyPlotOptions {
  int width_px = 960;
  int height_px = 540;
  double line_width_px = 2.0;
  std::string title = "Anchor positional uncertainty sqrt(sigma_x^2 + sigma_y^2)";
};

// Data (update, metres) to pixel mapping of a rendered plot.
struct PlotFrame {
  double left_px = 0, top_px = 0, right_px = 1, bottom_px = 1;  // the plot area
  double x_min = 0, x_max = 1, y_min = 0, y_max = 1;            // the data ranges shown
  Eigen::Vector2d ToPixel(double x, double y) const {
    return {left_px + (x - x_min) / (x_max - x_min) * (right_px - left_px),
            bottom_px - (y - y_min) / (y_max - y_min) * (bottom_px - top_px)};
  }
};

// Draws and writes the PNG (an empty plot with a note when there are no samples).
Status RenderUncertaintyPlot(const std::vector<AnchorSample>& samples,
                             const ColorAssignment& colors, const UncertaintyPlotOptions& options,
                             const std::string& path, PlotFrame* frame = nullptr);

// About `count` round tick values (1, 2 or 5 times a power of ten) covering [low, high].
std::vector<double> NiceTicks(double low, double high, int count);

}  // namespace anchormap::render
