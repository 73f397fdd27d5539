#pragma once
// For the render tests only: a synthetic server output log (what anchormap-server writes)
// and a PNG decoder through libpng, so that tests check the files with another library
// than the one that wrote them.

#include <png.h>

#include <cstdio>
#include <string>
#include <vector>

#include "anchormap/anchor_covariances_t.hpp"
#include "anchormap/grid_tile_t.hpp"
#include "anchormap/merged_map_t.hpp"
#include "anchormap/server_status_t.hpp"
#include "common/bus/authenticator.h"
#include "common/bus/channels.h"
#include "common/bus/lcm_log.h"
#include "tools/render/colors.h"

namespace anchormap::render::testing {

struct DecodedPng {
  int width = 0;
  int height = 0;
  std::vector<uint8_t> rgb;  // 3 bytes per pixel, row 0 at the top
  Rgb at(int x, int y) const {
    const size_t i = 3 * (static_cast<size_t>(y) * width + x);
    return {rgb[i], rgb[i + 1], rgb[i + 2]};
  }
};

// Decodes any PNG into 8-bit RGB with libpng's simplified API; false on failure.
inline bool DecodePng(const std::string& path, DecodedPng* out) {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&image, path.c_str())) return false;
  image.format = PNG_FORMAT_RGB;
  out->width = static_cast<int>(image.width);
  out->height = static_cast<int>(image.height);
  out->rgb.resize(PNG_IMAGE_SIZE(image));
  if (!png_image_finish_read(&image, nullptr, out->rgb.data(), 0, nullptr)) {
    png_image_free(&image);
    return false;
  }
  return true;
}

inline anchormap::trajectory_t MakeTrajectory(const std::string& robot, int64_t id, bool anchored,
                                              const std::vector<std::vector<double>>& poses) {
  anchormap::trajectory_t t;
  t.robot = robot;
  t.trajectory_id = id;
  t.anchored = anchored;
  t.anchor[0] = t.anchor[1] = t.anchor[2] = 0.0;
  t.num_poses = static_cast<int32_t>(poses.size());
  for (size_t i = 0; i < poses.size(); ++i) t.pose_utimes.push_back(1000000 * (i + 1));
  t.poses = poses;
  return t;
}

// The merged map used by the render tests: R1 (id 11) goes east along y = 2 from x = 0 to
// 8, R2 (id 12) north along x = 10 from y = 0 to 8, R3 (id 13) is not anchored; one
// encounter joins R1's last keyframe (8, 2) and R2's keyframe 1 (10, 2).
inline anchormap::merged_map_t TestMergedMap(int64_t update) {
  anchormap::merged_map_t map;
  map.utime = 5000000;
  map.update = update;
  map.trajectories.push_back(MakeTrajectory("R1", 11, true, {{0, 2, 0}, {4, 2, 0}, {8, 2, 0}}));
  map.trajectories.push_back(
      MakeTrajectory("R2", 12, true, {{10, 0, 1.57}, {10, 2, 1.57}, {10, 8, 1.57}}));
  map.trajectories.push_back(MakeTrajectory("R3", 13, false, {{1, 6, 0}, {3, 6, 0}}));
  map.num_trajectories = 3;
  anchormap::encounter_link_t link;
  link.robot_a = "R1";
  link.trajectory_a = 11;
  link.index_a = 2;
  link.robot_b = "R2";
  link.trajectory_b = 12;
  link.index_b = 1;
  link.kind = 0;  // direct (lcm-gen leaves plain fields uninitialised)
  map.encounters.push_back(link);
  map.num_encounters = 1;
  return map;
}

// A tile of `size` x `size` cells at 0.5 m, all free except column 0 (occupied).
inline anchormap::grid_tile_t TestTile(int64_t update, int tile_x, int tile_y, int size = 10) {
  anchormap::grid_tile_t tile;
  tile.utime = 5000000;
  tile.update = update;
  tile.resolution = 0.5;
  tile.tile_x = tile_x;
  tile.tile_y = tile_y;
  tile.width = size;
  tile.height = size;
  tile.cells.assign(size, std::vector<int8_t>(size, 0));
  for (auto& row : tile.cells) row[0] = 100;
  return tile;
}

inline anchormap::anchor_covariances_t TestCovariances(int64_t update, double r2_variance) {
  anchormap::anchor_covariances_t message;
  message.utime = update * 1000000;
  message.update = update;
  for (const auto& [robot, id, variance] : std::vector<std::tuple<std::string, int64_t, double>>{
           {"R1", 11, 1e-6}, {"R2", 12, r2_variance}}) {
    anchormap::anchor_covariance_t anchor;
    anchor.robot = robot;
    anchor.trajectory_id = id;
    anchor.anchor[0] = anchor.anchor[1] = anchor.anchor[2] = 0.0;
    for (double& c : anchor.covariance) c = 0.0;
    anchor.covariance[0] = variance;  // sigma_x^2
    anchor.covariance[4] = variance;  // sigma_y^2
    anchor.covariance[8] = 0.01;
    message.anchors.push_back(anchor);
  }
  message.num_anchors = static_cast<int32_t>(message.anchors.size());
  return message;
}

// Writes a server output log: two merged maps (updates 4 and 9), a 2 x 2 tile grid of
// update 9 covering [0, 10] x [0, 10], covariances for updates 1..9 in which R2's
// sigma_xy shrinks from 2 m to 0.4 m, and a server status (2 duplicates rejected). With
// `sealer` every message goes in its envelope, as anchormap-server --key-file sends them.
inline Status WriteTestServerLog(const std::string& path, Authenticator* sealer = nullptr) {
  LcmLogWriter writer;
  Status written = writer.Open(path);
  auto write = [&](const char* channel, int64_t utime, const auto& message) {
    if (!written.ok()) return;
    if (!sealer) {
      written = writer.Write(channel, utime, message);
      return;
    }
    std::vector<uint8_t> bytes(static_cast<size_t>(message.getEncodedSize()));
    message.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
    const std::vector<uint8_t> sealed = sealer->Seal(channel, bytes.data(), bytes.size());
    written = writer.WriteRaw(channel, utime, sealed.data(), sealed.size());
  };
  write(channels::kMergedMap, 1, TestMergedMap(4));
  write(channels::kGridTiles, 2, TestTile(4, 0, 0));
  for (int update = 1; update <= 9; ++update) {
    const double sigma_xy = 2.0 - 0.2 * (update - 1);  // 2.0 .. 0.4
    write(channels::kAnchorCovariances, 3 + update,
          TestCovariances(update, sigma_xy * sigma_xy / 2));
  }
  write(channels::kMergedMap, 20, TestMergedMap(9));
  anchormap::server_status_t status;
  status.utime = 20;
  status.update = 9;
  status.num_robots = 3;
  status.num_trajectories = 3;
  status.num_anchored = 2;
  status.keyframes = 8;
  status.encounters = 1;
  status.last_update_ms = 0.5;
  status.num_reasons = 1;
  status.rejection_reasons = {"duplicate_seq"};
  status.rejection_counts = {2};
  write(channels::kServerStatus, 20, status);
  for (int ty = 0; ty < 2; ++ty) {
    for (int tx = 0; tx < 2; ++tx) write(channels::kGridTiles, 21, TestTile(9, tx, ty));
  }
  writer.Close();
  return written;
}

}  // namespace anchormap::render::testing
