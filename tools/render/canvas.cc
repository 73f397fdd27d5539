#include "tools/render/canvas.h"

#include <cairo.h>

#include <algorithm>

namespace anchormap::render {

struct Canvas::Impl {
  cairo_surface_t* surface = nullptr;
  cairo_t* cr = nullptr;
};

namespace {

void SetColor(cairo_t* cr, const Rgb& color, double alpha) {
  cairo_set_source_rgba(cr, color.r / 255.0, color.g / 255.0, color.b / 255.0, alpha);
}

void SelectFont(cairo_t* cr, double size_px, bool bold) {
  cairo_select_font_face(cr, "DejaVu Sans", CAIRO_FONT_SLANT_NORMAL,
                         bold ? CAIRO_FONT_WEIGHT_BOLD : CAIRO_FONT_WEIGHT_NORMAL);
  cairo_set_font_size(cr, size_px);
}

}  // namespace

// Fontconfig (behind cairo's text) keeps its caches until exit by design; LeakSanitizer
// would report them in sanitizer builds. This hook, read only when LSan is linked in,
// suppresses exactly those.
extern "C" const char* __lsan_default_suppressions() { return "leak:libfontconfig.so\n"; }

Canvas::Canvas(int width_px, int height_px)
    : impl_(std::make_unique<Impl>()),
      width_(std::max(1, width_px)),
      height_(std::max(1, height_px)) {
  impl_->surface = cairo_image_surface_create(CAIRO_FORMAT_RGB24, width_, height_);
  impl_->cr = cairo_create(impl_->surface);
  cairo_set_source_rgb(impl_->cr, 1.0, 1.0, 1.0);
  cairo_paint(impl_->cr);
  cairo_set_line_join(impl_->cr, CAIRO_LINE_JOIN_ROUND);
  cairo_set_line_cap(impl_->cr, CAIRO_LINE_CAP_ROUND);
}

Canvas::~Canvas() {
  cairo_destroy(impl_->cr);
  cairo_surface_destroy(impl_->surface);
}

void Canvas::GrayImage(const std::vector<uint8_t>& gray, int image_width, int image_height,
                       double x, double y, double scale) {
  if (image_width <= 0 || image_height <= 0 ||
      gray.size() != static_cast<size_t>(image_width) * image_height) {
    return;
  }
  cairo_surface_t* image =
      cairo_image_surface_create(CAIRO_FORMAT_RGB24, image_width, image_height);
  cairo_surface_flush(image);
  unsigned char* data = cairo_image_surface_get_data(image);
  const int stride = cairo_image_surface_get_stride(image);
  for (int row = 0; row < image_height; ++row) {
    auto* pixels = reinterpret_cast<uint32_t*>(data + static_cast<size_t>(row) * stride);
    for (int col = 0; col < image_width; ++col) {
      const uint32_t g = gray[static_cast<size_t>(row) * image_width + col];
      pixels[col] = 0xff000000u | g << 16 | g << 8 | g;
    }
  }
  cairo_surface_mark_dirty(image);
  cairo_t* cr = impl_->cr;
  cairo_save(cr);
  cairo_translate(cr, x, y);
  cairo_scale(cr, scale, scale);
  cairo_set_source_surface(cr, image, 0, 0);
  cairo_pattern_set_filter(cairo_get_source(cr), CAIRO_FILTER_NEAREST);
  cairo_rectangle(cr, 0, 0, image_width, image_height);
  cairo_fill(cr);
  cairo_restore(cr);
  cairo_surface_destroy(image);
}

void Canvas::Polyline(const std::vector<Eigen::Vector2d>& points, const Rgb& color, double width_px,
                      double alpha, bool dashed) {
  if (points.empty()) return;
  cairo_t* cr = impl_->cr;
  cairo_save(cr);
  cairo_move_to(cr, points.front().x(), points.front().y());
  for (size_t i = 1; i < points.size(); ++i) cairo_line_to(cr, points[i].x(), points[i].y());
  if (points.size() == 1) cairo_line_to(cr, points.front().x(), points.front().y());
  if (dashed) {
    const double pattern[] = {4.0 * width_px, 3.0 * width_px};
    cairo_set_dash(cr, pattern, 2, 0.0);
  }
  SetColor(cr, color, alpha);
  cairo_set_line_width(cr, width_px);
  cairo_stroke(cr);
  cairo_restore(cr);
}

void Canvas::Line(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Rgb& color,
                  double width_px, double alpha) {
  Polyline({a, b}, color, width_px, alpha);
}

void Canvas::FillCircle(const Eigen::Vector2d& center, double radius_px, const Rgb& color) {
  cairo_t* cr = impl_->cr;
  cairo_new_path(cr);
  cairo_arc(cr, center.x(), center.y(), radius_px, 0.0, 6.283185307179586);
  SetColor(cr, color, 1.0);
  cairo_fill(cr);
}

void Canvas::FillRect(double x, double y, double w, double h, const Rgb& color, double alpha) {
  cairo_t* cr = impl_->cr;
  cairo_rectangle(cr, x, y, w, h);
  SetColor(cr, color, alpha);
  cairo_fill(cr);
}

void Canvas::StrokeRect(double x, double y, double w, double h, const Rgb& color, double width_px) {
  cairo_t* cr = impl_->cr;
  cairo_rectangle(cr, x, y, w, h);
  SetColor(cr, color, 1.0);
  cairo_set_line_width(cr, width_px);
  cairo_stroke(cr);
}

void Canvas::Text(double x, double y, const std::string& text, double size_px, const Rgb& color,
                  Align align, bool bold, bool rotate_ccw) {
  cairo_t* cr = impl_->cr;
  cairo_save(cr);
  SelectFont(cr, size_px, bold);
  cairo_text_extents_t extents;
  cairo_text_extents(cr, text.c_str(), &extents);
  double shift = 0.0;
  if (align == Align::kCenter) shift = -0.5 * extents.x_advance;
  if (align == Align::kRight) shift = -extents.x_advance;
  cairo_translate(cr, x, y);
  if (rotate_ccw) cairo_rotate(cr, -1.5707963267948966);
  cairo_move_to(cr, shift, 0.0);
  SetColor(cr, color, 1.0);
  cairo_show_text(cr, text.c_str());
  cairo_restore(cr);
}

double Canvas::TextWidth(const std::string& text, double size_px, bool bold) {
  cairo_t* cr = impl_->cr;
  cairo_save(cr);
  SelectFont(cr, size_px, bold);
  cairo_text_extents_t extents;
  cairo_text_extents(cr, text.c_str(), &extents);
  cairo_restore(cr);
  return extents.x_advance;
}

Status Canvas::WritePng(const std::string& path) {
  cairo_surface_flush(impl_->surface);
  const cairo_status_t status = cairo_surface_write_to_png(impl_->surface, path.c_str());
  if (status != CAIRO_STATUS_SUCCESS) {
    return Status::Error("cannot write PNG '" + path + "': " + cairo_status_to_string(status));
  }
  return Status::Ok();
}

}  // namespace anchormap::render
