#include "tools/render/map_export.h"

#include <filesystem>

#include "common/io/map_file.h"

namespace anchormap::render {

std::string YamlPathFor(const std::string& pgm_path) {
  std::filesystem::path path(pgm_path);
  path.replace_extension(".yaml");
  return path.string();
}

Status WriteMapServerFiles(const OccupancyRaster& raster, const std::string& pgm_path,
                           const std::string& yaml_path) {
  if (raster.empty()) return Status::Error("no occupancy grid to write");
  MapMetadata metadata;
  GrayImage image;
  image.width = raster.width;
  image.height = raster.height;
  image.max_value = 255;
  image.pixels.resize(raster.cells.size());
  for (int y = 0; y < raster.height; ++y) {
    for (int x = 0; x < raster.width; ++x) {
      image.pixels[static_cast<size_t>(raster.height - 1 - y) * raster.width + x] =
          OccupancyToPgmValue(raster.at(x, y), metadata);
    }
  }
  if (Status status = WritePgm(pgm_path, image); !status.ok()) return status;

  const std::filesystem::path yaml_dir = std::filesystem::absolute(yaml_path).parent_path();
  const std::filesystem::path pgm_abs = std::filesystem::absolute(pgm_path);
  metadata.image =
      pgm_abs.parent_path() == yaml_dir ? pgm_abs.filename().string() : pgm_abs.string();
  metadata.resolution_m = raster.resolution_m;
  metadata.origin[0] = raster.origin.x();
  metadata.origin[1] = raster.origin.y();
  metadata.origin[2] = 0.0;
  return WriteMapYaml(yaml_path, metadata);
}

}  // namespace anchormap::render
