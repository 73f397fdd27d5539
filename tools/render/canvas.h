#pragma once
// A white raster canvas in pixel coordinates (x right, y down) that draws lines, shapes,
// text and grey images with cairo and writes PNG files through cairo's libpng writer. The
// map and the uncertainty plot are drawn on it; cairo stays out of every other header.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/util/status.h"
#include "tools/render/colors.h"

namespace anchormap::render {

class Canvas {
 public:
  Canvas(int width_px, int height_px);  // white, opaque
  ~Canvas();
  Canvas(const Canvas&) = delete;
  Canvas& operator=(const Canvas&) = delete;

  int width() const { return width_; }
  int height() const { return height_; }

  // A grey image (row 0 at the top, 0 black .. 255 white) with its top-left corner at
  // (x, y), each image pixel drawn as a `scale` x `scale` block (no smoothing).
  void GrayImage(const std::vector<uint8_t>& gray, int image_width, int image_height, double x,
                 double y, double scale);
  void Polyline(const std::vector<Eigen::Vector2d>& points, const Rgb& color, double width_px,
                double alpha = 1.0, bool dashed = false);
  void Line(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Rgb& color, double width_px,
            double alpha = 1.0);
  void FillCircle(const Eigen::Vector2d& center, double radius_px, const Rgb& color);
  void FillRect(double x, double y, double w, double h, const Rgb& color, double alpha = 1.0);
  void StrokeRect(double x, double y, double w, double h, const Rgb& color, double width_px);

  enum class Align { kLeft, kCenter, kRight };
  // Text with its baseline at y; `rotate_ccw` turns it by 90 degrees (a y-axis label).
  void Text(double x, double y, const std::string& text, double size_px, const Rgb& color,
            Align align = Align::kLeft, bool bold = false, bool rotate_ccw = false);
  double TextWidth(const std::string& text, double size_px, bool bold = false);

  Status WritePng(const std::string& path);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  int width_;
  int height_;
};

}  // namespace anchormap::render
