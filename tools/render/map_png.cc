#include "tools/render/map_png.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "tools/render/canvas.h"

namespace anchormap::render {
namespace {

constexpr Rgb kBlack{0, 0, 0};
constexpr Rgb kDark{40, 40, 40};
// Encounter links by kind: direct encounters dark, scan encounters magenta (no trajectory
// colour is close), loop closures light grey and thin (there are hundreds).
constexpr Rgb kScanEncounterColor{220, 0, 170};
constexpr Rgb kLoopClosureColor{150, 150, 150};
constexpr Rgb kWhite{255, 255, 255};
constexpr Rgb kFrame{120, 120, 120};

// 1, 2 or 5 times a power of ten, near `target`.
double NiceLength(double target) {
  const double power = std::pow(10.0, std::floor(std::log10(target)));
  for (double step : {1.0, 2.0, 5.0}) {
    if (step * power >= target * 0.7) return step * power;
  }
  return 10.0 * power;
}

std::string Format(const char* format, double a, double b = 0.0, double c = 0.0) {
  char buffer[256];
  std::snprintf(buffer, sizeof(buffer), format, a, b, c);
  return buffer;
}

}  // namespace

uint8_t OccupancyGray(int8_t occupancy) {
  // map_saver's thresholds: at most 19.6 % is free (white), at least 65 % occupied (black);
  // in between a grey ramp, so that uncertain cells stay visible.
  constexpr double kFree = 19.6;
  constexpr double kOccupied = 65.0;
  if (occupancy < 0) return 205;
  if (occupancy <= kFree) return 255;
  if (occupancy >= kOccupied) return 0;
  return static_cast<uint8_t>(std::lround(255.0 * (kOccupied - occupancy) / (kOccupied - kFree)));
}

MapViewport ChooseViewport(const MergedMap* map, const OccupancyRaster& raster,
                           const MapPngOptions& options) {
  bool any = false;
  Eigen::Vector2d low(0.0, 0.0);
  Eigen::Vector2d high(0.0, 0.0);
  auto extend = [&](const Eigen::Vector2d& p) {
    low = any ? low.cwiseMin(p) : p;
    high = any ? high.cwiseMax(p) : p;
    any = true;
  };
  if (!raster.empty()) {
    extend(raster.origin);
    extend(raster.max_corner());
  }
  if (map) {
    for (const TrajectoryView& t : map->trajectories) {
      for (const Pose2& pose : t.poses) extend(pose.translation());
    }
  }
  if (!any) high = Eigen::Vector2d(10.0, 10.0);
  MapViewport viewport;
  viewport.world_min = low - Eigen::Vector2d::Constant(options.margin_m);
  viewport.world_max = high + Eigen::Vector2d::Constant(options.margin_m);
  const Eigen::Vector2d extent = viewport.world_max - viewport.world_min;
  double ppm = options.pixels_per_m > 0.0
                   ? options.pixels_per_m
                   : std::clamp(options.target_side_px / extent.maxCoeff(), 2.0, 100.0);
  ppm = std::min(ppm, (options.max_side_px - viewport.header_px) / extent.maxCoeff());
  viewport.pixels_per_m = ppm;
  viewport.width_px = std::max(320, static_cast<int>(std::ceil(extent.x() * ppm)));
  viewport.height_px = viewport.header_px + static_cast<int>(std::ceil(extent.y() * ppm));
  // A minimum width for the title: centre the world in it.
  if (viewport.width_px > extent.x() * ppm + 1.0) {
    const double pad_m = (viewport.width_px / ppm - extent.x()) / 2.0;
    viewport.world_min.x() -= pad_m;
    viewport.world_max.x() += pad_m;
  }
  return viewport;
}

Status RenderMapPng(const MergedMap* map, const OccupancyRaster& raster,
                    const ColorAssignment& colors, const MapPngOptions& options,
                    const std::string& path, MapViewport* viewport_out) {
  const MapViewport view = ChooseViewport(map, raster, options);
  Canvas canvas(view.width_px, view.height_px);

  if (!raster.empty()) {
    // The raster's row 0 is at the bottom; the image's at the top.
    std::vector<uint8_t> gray(raster.cells.size());
    for (int y = 0; y < raster.height; ++y) {
      for (int x = 0; x < raster.width; ++x) {
        gray[static_cast<size_t>(raster.height - 1 - y) * raster.width + x] =
            OccupancyGray(raster.at(x, y));
      }
    }
    const Eigen::Vector2d top_left =
        view.ToPixel({raster.origin.x(), raster.origin.y() + raster.height * raster.resolution_m});
    canvas.GrayImage(gray, raster.width, raster.height, top_left.x(), top_left.y(),
                     raster.resolution_m * view.pixels_per_m);
  }

  size_t keyframes = 0;
  if (map) {
    for (const TrajectoryView& t : map->trajectories) {
      std::vector<Eigen::Vector2d> points;
      for (const Pose2& pose : t.poses) points.push_back(view.ToPixel(pose.translation()));
      keyframes += points.size();
      const Rgb color = colors.ColorOf(t.key);
      canvas.Polyline(points, color, options.trajectory_width_px, t.anchored ? 1.0 : 0.6,
                      !t.anchored);
      if (!points.empty())
        canvas.FillCircle(points.front(), 2.5 * options.trajectory_width_px, color);
    }
    if (options.draw_encounters) {
      for (const EncounterLink& link : map->encounters) {
        const Pose2* a = map->FindPose(link.a, link.index_a);
        const Pose2* b = map->FindPose(link.b, link.index_b);
        if (!a || !b) continue;
        switch (link.kind) {
          case ConstraintKind::kDirectEncounter:
            canvas.Line(view.ToPixel(a->translation()), view.ToPixel(b->translation()), kDark, 1.5,
                        0.8);
            break;
          case ConstraintKind::kScanEncounter:
            canvas.Line(view.ToPixel(a->translation()), view.ToPixel(b->translation()),
                        kScanEncounterColor, 1.5, 0.8);
            break;
          case ConstraintKind::kLoopClosure:
            canvas.Line(view.ToPixel(a->translation()), view.ToPixel(b->translation()),
                        kLoopClosureColor, 1.0, 0.6);
            break;
        }
      }
    }
  }

  // Title band.
  canvas.FillRect(0, 0, view.width_px, view.header_px, {245, 245, 245});
  int by_kind[kNumConstraintKinds] = {};
  if (map) {
    for (const EncounterLink& link : map->encounters) ++by_kind[static_cast<int>(link.kind)];
  }
  std::string title = options.title;
  if (map) {
    title += Format("   update %.0f: %.0f trajectories, %.0f keyframes",
                    static_cast<double>(map->update), static_cast<double>(map->trajectories.size()),
                    static_cast<double>(keyframes));
    title += Format(", encounters: %.0f direct (dark)", static_cast<double>(by_kind[0]));
    title += Format(", %.0f scan (magenta)", static_cast<double>(by_kind[1]));
    title += Format(", %.0f loop closures (grey)", static_cast<double>(by_kind[2]));
  } else {
    title += "   (no merged map in the log)";
  }
  if (raster.empty()) title += ", no grid";
  // A long title (a user's --title plus the counts) is set smaller rather than cut off.
  // Hinting makes a text's width not quite proportional to its size: measure again.
  const double title_room_px = view.width_px - 20.0;
  double title_size_px = 16.0;
  for (int i = 0; i < 8 && title_size_px > 8.0; ++i) {
    const double width_px = canvas.TextWidth(title, title_size_px, true);
    if (width_px <= title_room_px) break;
    title_size_px = std::max(8.0, 0.98 * title_size_px * title_room_px / width_px);
  }
  canvas.Text(10, 26, title, title_size_px, kBlack, Canvas::Align::kLeft, true);

  // Legend (top-left, over the map).
  if (map && !map->trajectories.empty()) {
    const double row = 18.0;
    const size_t shown = std::min<size_t>(map->trajectories.size(), 24);
    double width = 0.0;
    std::vector<std::string> labels;
    for (size_t i = 0; i < shown; ++i) {
      const TrajectoryView& t = map->trajectories[i];
      // The id in full: agents draw 63-bit ids, which a double would round.
      labels.push_back(t.key.robot + " (trajectory " + std::to_string(t.key.trajectory_id) +
                       Format("): %.0f keyframes", static_cast<double>(t.poses.size())) +
                       (t.anchored ? "" : ", not anchored"));
      width = std::max(width, canvas.TextWidth(labels.back(), 12));
    }
    if (shown < map->trajectories.size()) {
      labels.push_back(Format("... and %.0f more", double(map->trajectories.size() - shown)));
    }
    // Then the constraint kinds, each with its line.
    struct KindRow {
      ConstraintKind kind;
      const char* label;
      Rgb color;
      double width_px;
    };
    const KindRow kinds[] = {
        {ConstraintKind::kDirectEncounter, "direct encounters: %.0f", kDark, 1.5},
        {ConstraintKind::kScanEncounter, "scan encounters: %.0f", kScanEncounterColor, 1.5},
        {ConstraintKind::kLoopClosure, "loop closures: %.0f", kLoopClosureColor, 1.0}};
    const size_t first_kind = labels.size();
    if (options.draw_encounters) {
      for (const KindRow& k : kinds) {
        labels.push_back(Format(k.label, static_cast<double>(by_kind[static_cast<int>(k.kind)])));
        width = std::max(width, canvas.TextWidth(labels.back(), 12));
      }
    }
    const double x0 = 8;
    const double y0 = view.header_px + 8;
    const double height = row * labels.size() + 8;
    canvas.FillRect(x0, y0, width + 44, height, kWhite, 0.85);
    canvas.StrokeRect(x0, y0, width + 44, height, kFrame, 1.0);
    for (size_t i = 0; i < labels.size(); ++i) {
      const double y = y0 + 4 + row * (i + 0.5);
      if (i < shown) {
        const TrajectoryView& t = map->trajectories[i];
        canvas.Polyline({{x0 + 8, y}, {x0 + 32, y}}, colors.ColorOf(t.key), 3.0, 1.0, !t.anchored);
      } else if (i >= first_kind) {
        // Drawn thicker than on the map, so that the colour reads at legend size.
        const KindRow& k = kinds[i - first_kind];
        canvas.Line({x0 + 8, y}, {x0 + 32, y}, k.color, 2.0 * k.width_px, 1.0);
      }
      canvas.Text(x0 + 38, y + 4, labels[i], 12, kBlack);
    }
  }

  // Scale bar (bottom-left).
  const double bar_m = NiceLength(120.0 / view.pixels_per_m);
  const double bar_px = bar_m * view.pixels_per_m;
  const double bx = 14;
  const double by = view.height_px - 16;
  canvas.FillRect(bx - 6, by - 22, bar_px + 12, 30, kWhite, 0.85);
  canvas.FillRect(bx, by - 4, bar_px, 4, kBlack);
  canvas.Text(bx + bar_px / 2, by - 8, Format(bar_m >= 1.0 ? "%.0f m" : "%.1f m", bar_m), 12,
              kBlack, Canvas::Align::kCenter);

  if (viewport_out) *viewport_out = view;
  return canvas.WritePng(path);
}

}  // namespace anchormap::render
