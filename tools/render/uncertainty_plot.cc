#include "tools/render/uncertainty_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>

#include "tools/render/canvas.h"

namespace anchormap::render {
namespace {

constexpr Rgb kBlack{0, 0, 0};
constexpr Rgb kGridLine{225, 225, 225};
constexpr Rgb kAxis{60, 60, 60};

std::string TickLabel(double value, double step) {
  char buffer[64];
  const int decimals = step >= 1.0 ? 0 : static_cast<int>(std::ceil(-std::log10(step) - 1e-9));
  std::snprintf(buffer, sizeof(buffer), "%.*f", std::min(decimals, 6), value);
  return buffer;
}

}  // namespace

std::vector<double> NiceTicks(double low, double high, int count) {
  if (!(high > low) || count < 1) return {low};
  const double raw = (high - low) / count;
  const double power = std::pow(10.0, std::floor(std::log10(raw)));
  double step = 10.0 * power;
  for (double m : {1.0, 2.0, 5.0}) {
    if (m * power >= raw) {
      step = m * power;
      break;
    }
  }
  std::vector<double> ticks;
  for (double v = std::ceil(low / step - 1e-9) * step; v <= high + 1e-9 * step; v += step) {
    ticks.push_back(std::abs(v) < 1e-12 * step ? 0.0 : v);
  }
  return ticks;
}

Status RenderUncertaintyPlot(const std::vector<AnchorSample>& samples,
                             const ColorAssignment& colors, const UncertaintyPlotOptions& options,
                             const std::string& path, PlotFrame* frame_out) {
  Canvas canvas(options.width_px, options.height_px);
  // One series per anchor, in natural trajectory order.
  std::map<TrajectoryKey, std::vector<Eigen::Vector2d>> series;
  for (const AnchorSample& s : samples) {
    series[s.key].emplace_back(static_cast<double>(s.update), s.sigma_xy_m);
  }

  PlotFrame frame;
  double legend_width = 0.0;
  for (const auto& [key, points] : series) {
    legend_width =
        std::max(legend_width,
                 canvas.TextWidth(
                     key.robot + " (trajectory " + std::to_string(key.trajectory_id) + ")", 12));
  }
  frame.left_px = 80;
  frame.top_px = 50;
  frame.right_px = options.width_px - (series.empty() ? 30 : legend_width + 70);
  frame.bottom_px = options.height_px - 60;
  if (!samples.empty()) {
    frame.x_min = frame.x_max = static_cast<double>(samples.front().update);
    frame.y_max = 0.0;
    for (const AnchorSample& s : samples) {
      frame.x_min = std::min(frame.x_min, static_cast<double>(s.update));
      frame.x_max = std::max(frame.x_max, static_cast<double>(s.update));
      frame.y_max = std::max(frame.y_max, s.sigma_xy_m);
    }
    if (frame.x_max <= frame.x_min) frame.x_max = frame.x_min + 1.0;
    frame.y_max = frame.y_max > 0.0 ? frame.y_max * 1.08 : 1.0;
  }
  frame.y_min = 0.0;

  // Grid, ticks and labels.
  const auto x_ticks = NiceTicks(frame.x_min, frame.x_max, 8);
  const auto y_ticks = NiceTicks(frame.y_min, frame.y_max, 6);
  const double x_step = x_ticks.size() > 1 ? x_ticks[1] - x_ticks[0] : 1.0;
  const double y_step = y_ticks.size() > 1 ? y_ticks[1] - y_ticks[0] : 1.0;
  for (double x : x_ticks) {
    const Eigen::Vector2d p = frame.ToPixel(x, frame.y_min);
    canvas.Line({p.x(), frame.top_px}, {p.x(), frame.bottom_px}, kGridLine, 1.0);
    canvas.Line({p.x(), frame.bottom_px}, {p.x(), frame.bottom_px + 5}, kAxis, 1.0);
    canvas.Text(p.x(), frame.bottom_px + 20, TickLabel(x, x_step), 12, kBlack,
                Canvas::Align::kCenter);
  }
  for (double y : y_ticks) {
    const Eigen::Vector2d p = frame.ToPixel(frame.x_min, y);
    canvas.Line({frame.left_px, p.y()}, {frame.right_px, p.y()}, kGridLine, 1.0);
    canvas.Line({frame.left_px - 5, p.y()}, {frame.left_px, p.y()}, kAxis, 1.0);
    canvas.Text(frame.left_px - 9, p.y() + 4, TickLabel(y, y_step), 12, kBlack,
                Canvas::Align::kRight);
  }
  canvas.StrokeRect(frame.left_px, frame.top_px, frame.right_px - frame.left_px,
                    frame.bottom_px - frame.top_px, kAxis, 1.0);
  canvas.Text(options.width_px / 2.0, 28, options.title, 15, kBlack, Canvas::Align::kCenter, true);
  canvas.Text((frame.left_px + frame.right_px) / 2, options.height_px - 16, "solver update", 13,
              kBlack, Canvas::Align::kCenter);
  canvas.Text(24, (frame.top_px + frame.bottom_px) / 2, "anchor uncertainty [m]", 13, kBlack,
              Canvas::Align::kCenter, false, true);
  if (series.empty()) {
    canvas.Text((frame.left_px + frame.right_px) / 2, (frame.top_px + frame.bottom_px) / 2,
                "no anchor covariances in the log", 14, kAxis, Canvas::Align::kCenter);
  }

  // Lines and legend.
  double legend_y = frame.top_px + 10;
  size_t legend_entries = 0;
  bool legend_full = false;
  for (const auto& [key, points] : series) {
    const Rgb color = colors.ColorOf(key);
    std::vector<Eigen::Vector2d> pixels;
    for (const Eigen::Vector2d& p : points) pixels.push_back(frame.ToPixel(p.x(), p.y()));
    canvas.Polyline(pixels, color, options.line_width_px);
    if (pixels.size() == 1) canvas.FillCircle(pixels.front(), 3.0, color);
    // The legend holds as many entries as fit; the last line counts the rest.
    ++legend_entries;
    if (legend_y + 36 > options.height_px && legend_entries < series.size()) {
      if (!legend_full) {
        canvas.Text(frame.right_px + 14, legend_y + 4,
                    "... and " + std::to_string(series.size() - legend_entries + 1) + " more", 12,
                    kBlack);
      }
      legend_full = true;
      continue;
    }
    canvas.Line({frame.right_px + 14, legend_y}, {frame.right_px + 38, legend_y}, color, 3.0);
    canvas.Text(frame.right_px + 44, legend_y + 4,
                key.robot + " (trajectory " + std::to_string(key.trajectory_id) + ")", 12, kBlack);
    legend_y += 18;
  }
  if (frame_out) *frame_out = frame;
  return canvas.WritePng(path);
}

}  // namespace anchormap::render
