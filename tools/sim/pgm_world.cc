#include "tools/sim/pgm_world.h"

#include <cmath>
#include <filesystem>

namespace anchormap::sim {
namespace {

enum class Cell : uint8_t { kFree, kUnknown, kOccupied };

class CellGrid {
 public:
  CellGrid(const GrayImage& image, const MapMetadata& metadata)
      : width_(image.width), height_(image.height), cells_(image.pixels.size()) {
    for (int row = 0; row < height_; ++row) {
      for (int x = 0; x < width_; ++x) {
        double occupancy = static_cast<double>(image.max_value - image.at(x, row)) /
                           static_cast<double>(image.max_value);
        if (metadata.negate != 0) occupancy = 1.0 - occupancy;
        Cell cell = Cell::kUnknown;
        if (occupancy > metadata.occupied_thresh) cell = Cell::kOccupied;
        if (occupancy < metadata.free_thresh) cell = Cell::kFree;
        // Image row 0 is the top; grid row 0 the bottom.
        cells_[static_cast<size_t>(height_ - 1 - row) * width_ + x] = cell;
      }
    }
  }
  int width() const { return width_; }
  int height() const { return height_; }
  bool Occupied(int x, int y) const {
    if (x < 0 || y < 0 || x >= width_ || y >= height_) return false;
    return cells_[static_cast<size_t>(y) * width_ + x] == Cell::kOccupied;
  }
  bool Free(int x, int y) const {
    return cells_[static_cast<size_t>(y) * width_ + x] == Cell::kFree;
  }

 private:
  int width_;
  int height_;
  std::vector<Cell> cells_;
};

}  // namespace

FloorPlan FloorPlanFromImage(const GrayImage& image, const MapMetadata& metadata) {
  const CellGrid grid(image, metadata);
  const double res = metadata.resolution_m;
  const Eigen::Vector2d origin(metadata.origin[0], metadata.origin[1]);
  FloorPlan plan;
  auto corner = [&](int x, int y) -> Eigen::Vector2d {
    return origin + Eigen::Vector2d(x, y) * res;
  };

  // Vertical borders: the line x = i between columns i-1 and i, wherever exactly one side
  // is occupied; runs of consecutive rows become one segment.
  for (int i = 0; i <= grid.width(); ++i) {
    int run_start = -1;
    for (int y = 0; y <= grid.height(); ++y) {
      const bool border = y < grid.height() && grid.Occupied(i - 1, y) != grid.Occupied(i, y);
      if (border && run_start < 0) run_start = y;
      if (!border && run_start >= 0) {
        plan.walls.push_back({corner(i, run_start), corner(i, y)});
        run_start = -1;
      }
    }
  }
  // Horizontal borders: the line y = j between rows j-1 and j.
  for (int j = 0; j <= grid.height(); ++j) {
    int run_start = -1;
    for (int x = 0; x <= grid.width(); ++x) {
      const bool border = x < grid.width() && grid.Occupied(x, j - 1) != grid.Occupied(x, j);
      if (border && run_start < 0) run_start = x;
      if (!border && run_start >= 0) {
        plan.walls.push_back({corner(run_start, j), corner(x, j)});
        run_start = -1;
      }
    }
  }

  plan.mask.width = grid.width();
  plan.mask.height = grid.height();
  plan.mask.resolution_m = res;
  plan.mask.origin = origin;
  plan.mask.free.resize(static_cast<size_t>(grid.width()) * grid.height());
  for (int y = 0; y < grid.height(); ++y) {
    for (int x = 0; x < grid.width(); ++x) {
      plan.mask.free[static_cast<size_t>(y) * grid.width() + x] = grid.Free(x, y) ? 1 : 0;
    }
  }
  return plan;
}

Status LoadPgmWorld(const std::string& path, double resolution_m, FloorPlan* plan) {
  MapMetadata metadata;
  std::string image_path = path;
  const std::filesystem::path fs_path(path);
  if (fs_path.extension() == ".yaml" || fs_path.extension() == ".yml") {
    if (Status status = ReadMapYaml(path, &metadata); !status.ok()) return status;
    if (std::abs(metadata.origin[2]) > 1e-9) {
      return Status::Error("'" + path + "': a rotated map origin (yaw != 0) is not supported");
    }
    const std::filesystem::path image(metadata.image);
    image_path = image.is_absolute() ? image.string() : (fs_path.parent_path() / image).string();
  } else {
    if (!(resolution_m > 0.0)) return Status::Error("world resolution must be > 0");
    metadata.resolution_m = resolution_m;
  }
  GrayImage image;
  if (Status status = ReadPgm(image_path, &image); !status.ok()) return status;
  *plan = FloorPlanFromImage(image, metadata);
  if (plan->walls.empty()) return Status::Error("'" + image_path + "' has no occupied pixels");
  size_t free_cells = 0;
  for (uint8_t f : plan->mask.free) free_cells += f;
  if (free_cells == 0) return Status::Error("'" + image_path + "' has no free pixels");
  return Status::Ok();
}

}  // namespace anchormap::sim
