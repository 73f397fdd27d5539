#pragma once
// Occupancy maps as files in the ROS map_server convention: a PGM image (binary P5, or
// ASCII P2 when reading) plus a YAML file with `image`, `resolution`, `origin`, `negate`,
// `occupied_thresh` and `free_thresh`. Written by anchormap-render, read by anchormap-sim
// (a rendered map can be simulated again).

#include <cstdint>
#include <string>
#include <vector>

#include "common/util/status.h"

namespace anchormap {

// A grey image as stored in the file: row 0 is the TOP row.
struct GrayImage {
  int width = 0;
  int height = 0;
  int max_value = 255;           // 1..65535
  std::vector<uint16_t> pixels;  // row-major, width * height

  uint16_t at(int x, int y) const { return pixels[static_cast<size_t>(y) * width + x]; }
};

// Reads P5 (8- or 16-bit) and P2 files, with '#' comments in the header.
Status ReadPgm(const std::string& path, GrayImage* image);
// Writes binary P5 (8-bit when max_value <= 255, else 16-bit big-endian).
Status WritePgm(const std::string& path, const GrayImage& image);

struct MapMetadata {
  std::string image;             // PGM path, relative to the YAML file's folder
  double resolution_m = 0.05;    // metres per pixel
  double origin[3] = {0, 0, 0};  // world pose (x, y, yaw) of the lower-left pixel's corner
  int negate = 0;                // 0: white is free, black is occupied
  double occupied_thresh = 0.65;
  double free_thresh = 0.196;
};

Status WriteMapYaml(const std::string& path, const MapMetadata& metadata);
// Reads the keys above from a map_server YAML file (flat "key: value" lines; the origin
// as a "[x, y, yaw]" list); fails on a missing `image` or `resolution`.
Status ReadMapYaml(const std::string& path, MapMetadata* metadata);

// map_saver's trinary values: occupancy (0..100, -1 unknown) -> 254 free, 0 occupied,
// 205 unknown or in between.
uint8_t OccupancyToPgmValue(int occupancy_percent, const MapMetadata& metadata = {});

}  // namespace anchormap
