#pragma once
// What anchormap-render needs from the server's output LCM log, as plain values: the last
// complete merged map (MergedMapAssembler: header and chunks, or one merged_map_t in older
// logs), the grid tiles of the last grid update, and every anchor-covariance message
// (for the uncertainty plot). Messages that do not decode are counted, never fatal.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "common/types/constraint_kind.h"

#include "common/bus/authenticator.h"
#include "common/bus/channels.h"
#include "common/geometry/pose2.h"
#include "common/util/status.h"
#include "tools/render/colors.h"

namespace anchormap::render {

struct TrajectoryView {
  TrajectoryKey key;
  bool anchored = false;
  Pose2 T_global_local;         // identity while unanchored
  std::vector<int64_t> utimes;  // one per keyframe
  std::vector<Pose2> poses;     // global frame (local frame while unanchored)
};

struct EncounterLink {
  TrajectoryKey a;  // robot + trajectory id (ids are unique per robot only)
  int index_a = 0;  // keyframe index within a's poses
  TrajectoryKey b;
  int index_b = 0;
  ConstraintKind kind = ConstraintKind::kDirectEncounter;  // drawn in its own colour
};

struct MergedMap {
  int64_t utime = 0;
  int64_t update = 0;
  std::vector<TrajectoryView> trajectories;
  std::vector<EncounterLink> encounters;

  // The pose a link end refers to, or nullptr when the trajectory or index is unknown.
  const Pose2* FindPose(const TrajectoryKey& trajectory, int index) const;
  size_t NumPoses() const;
};

// One tile of the occupancy grid (anchormap.grid_tile_t as a value).
struct GridTile {
  int64_t update = 0;
  double resolution_m = 0.05;
  int tile_x = 0;
  int tile_y = 0;
  int width = 0;
  int height = 0;
  std::vector<int8_t> cells;  // row-major, row 0 at the bottom; 0..100, -1 unknown
};

// One anchor's positional uncertainty after one solver update.
struct AnchorSample {
  int64_t update = 0;
  int64_t utime = 0;
  TrajectoryKey key;
  double sigma_xy_m = 0.0;  // sqrt(sigma_x^2 + sigma_y^2)
};

// The server's last status message (anchormap.server_status_t as a value).
struct ServerStatus {
  int64_t update = 0;
  int num_robots = 0;
  int num_trajectories = 0;
  int num_anchored = 0;
  int64_t keyframes = 0;
  int64_t encounters = 0;
  std::vector<std::pair<std::string, int64_t>> rejections;  // reason, count
};

struct ChannelNames {
  std::string map_header = channels::kMapHeader;
  std::string map_chunks = channels::kMapChunks;
  std::string merged_map = channels::kMergedMap;  // logs of servers before the chunks
  std::string server_status = channels::kServerStatus;
  std::string grid_tiles = channels::kGridTiles;
  std::string anchor_covariances = channels::kAnchorCovariances;
};

struct ServerOutput {
  std::optional<MergedMap> map;  // the last complete merged map in the log
  // The grid: the newest version of every tile (a grid update is a run of tiles with one
  // update number; the server sends the tiles that changed). In logs of servers before
  // that, which sent every tile each time, a tile their grid left stays as it was last sent.
  std::vector<GridTile> grid;
  int64_t grid_tiles_from_earlier_updates = 0;
  int64_t grid_update = 0;                   // the last grid update's number
  std::vector<AnchorSample> anchor_samples;  // in log order
  std::optional<ServerStatus> status;        // the last status message
  int64_t merged_maps = 0;                   // complete merged maps, then messages per kind
  int64_t grid_tile_messages = 0;
  int64_t covariance_messages = 0;
  int64_t undecodable = 0;      // messages on our channels that failed to decode or validate
  int64_t unauthenticated = 0;  // with a key: messages on our channels whose envelope was refused
  int64_t dangling_links = 0;   // encounter links to unknown keyframes (last map)
};

// Reads `path`; fails only when the file cannot be opened. With `authenticator` (the
// server's --key-file) only messages in a valid envelope are read (anchormap-server signs
// its outputs); the others are counted.
Status ReadServerOutput(const std::string& path, const ChannelNames& channels, ServerOutput* output,
                        Authenticator* authenticator = nullptr);

}  // namespace anchormap::render
