#include "tools/sim/sim_preview.h"

#include <algorithm>

#include "tools/render/canvas.h"
#include "tools/sim/robot_sim.h"

namespace anchormap::sim {

Status WriteSimPreviewPng(const World& world, const SimTrace& trace, const std::string& path,
                          double pixels_per_m) {
  using render::Canvas;
  const Eigen::Vector2d low = world.min_corner() - Eigen::Vector2d::Constant(1.0);
  const Eigen::Vector2d high = world.max_corner() + Eigen::Vector2d::Constant(1.0);
  const Eigen::Vector2d extent = high - low;
  const double ppm =
      pixels_per_m > 0.0 ? pixels_per_m : std::clamp(1400.0 / extent.maxCoeff(), 2.0, 60.0);
  const int header = 36;
  Canvas canvas(static_cast<int>(extent.x() * ppm) + 1,
                header + static_cast<int>(extent.y() * ppm) + 1);
  auto pixel = [&](const Eigen::Vector2d& p) -> Eigen::Vector2d {
    return {(p.x() - low.x()) * ppm, header + (high.y() - p.y()) * ppm};
  };
  for (const WallSegment& wall : world.walls()) {
    canvas.Line(pixel(wall.a), pixel(wall.b), {0, 0, 0}, std::max(1.5, 0.1 * ppm));
  }
  for (const auto& [a, b] : trace.encounters)
    canvas.Line(pixel(a), pixel(b), {90, 90, 90}, 1.0, 0.5);
  for (size_t i = 0; i < trace.paths.size(); ++i) {
    std::vector<Eigen::Vector2d> points;
    for (const Eigen::Vector2d& p : trace.paths[i]) points.push_back(pixel(p));
    const render::Rgb color = render::TrajectoryColor(static_cast<int>(i));
    canvas.Polyline(points, color, 2.0, 0.9);
    if (!points.empty()) {
      canvas.FillCircle(points.front(), 5.0, color);
      canvas.Text(points.front().x() + 7, points.front().y() - 7, RobotName(static_cast<int>(i)),
                  13, color, Canvas::Align::kLeft, true);
    }
  }
  canvas.FillRect(0, 0, canvas.width(), header, {245, 245, 245});
  canvas.Text(10, 24,
              "anchormap-sim ground truth: " + std::to_string(trace.paths.size()) + " robots, " +
                  std::to_string(trace.encounters.size()) + " encounters (grey lines)",
              15, {0, 0, 0}, Canvas::Align::kLeft, true);
  return canvas.WritePng(path);
}

}  // namespace anchormap::sim
