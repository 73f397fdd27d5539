#pragma once
// The mapping server's outputs as plain values (no LCM): the merged map, the anchors'
// covariances, occupancy-grid tiles and the status. The codec turns them into
// anchormap.merged_map_t, anchor_covariances_t, grid_tile_t and server_status_t.

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/types/constraint_kind.h"

namespace anchormap {

// One trajectory of the merged map.
struct MergedTrajectory {
  std::string robot;
  int64_t trajectory_id = 0;  // the agent's id (not the solver's)
  bool anchored = false;      // false until the trajectory's first encounter
  Pose2 T_global_local;       // identity while unanchored
  std::vector<int64_t> pose_utimes;
  // Keyframe poses in the global frame (the local frame while unanchored).
  std::vector<Pose2> poses;
};

// An encounter in the map: the two keyframes it joins (robot + agent trajectory id, which
// is unique per robot only; keyframe indices in pose order of the merged map), and what
// found it (a loop closure joins two keyframes of one trajectory).
struct EncounterLink {
  std::string robot_a;
  int64_t trajectory_a = 0;
  int32_t index_a = 0;
  std::string robot_b;
  int64_t trajectory_b = 0;
  int32_t index_b = 0;
  ConstraintKind kind = ConstraintKind::kDirectEncounter;

  bool operator==(const EncounterLink& o) const {
    return robot_a == o.robot_a && trajectory_a == o.trajectory_a && index_a == o.index_a &&
           robot_b == o.robot_b && trajectory_b == o.trajectory_b && index_b == o.index_b &&
           kind == o.kind;
  }
  bool operator!=(const EncounterLink& o) const { return !(*this == o); }
};

struct MergedMap {
  int64_t utime = 0;   // time of the newest input the map includes (data time)
  int64_t update = 0;  // solver update number
  std::vector<MergedTrajectory> trajectories;
  std::vector<EncounterLink> encounters;
};

// The merged map on the bus: a header and chunks of bounded size (anchormap.
// merged_map_header_t and merged_map_chunk_t say what each field means), so that one lost
// datagram loses one chunk, and a map update sends only the chunks that changed.
// server/map_chunker.h splits a MergedMap, common/bus/merged_map_assembler.h puts it back.
struct MergedMapHeader {
  struct Trajectory {
    std::string robot;
    int64_t trajectory_id = 0;
    bool anchored = false;
    Pose2 T_global_local;
    int32_t num_poses = 0;
    std::vector<int64_t> chunk_versions;  // ceil(num_poses / chunk_poses) of them
  };
  int64_t utime = 0;
  int64_t update = 0;
  int32_t chunk_poses = 0;
  std::vector<Trajectory> trajectories;
  int32_t num_encounters = 0;
};

struct MergedMapChunk {
  int64_t utime = 0;
  int64_t version = 0;
  std::string robot;
  int64_t trajectory_id = 0;
  int32_t chunk_index = 0;
  std::vector<int64_t> pose_utimes;
  std::vector<Pose2> local_poses;  // in the trajectory's local frame
  std::vector<EncounterLink> encounters;
  std::vector<int32_t> encounter_positions;  // in the map's encounter list, one per encounter
};

struct AnchorCovariance {
  std::string robot;
  int64_t trajectory_id = 0;
  Pose2 T_global_local;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();  // (x, y, theta), global frame
};

struct AnchorCovariances {
  int64_t utime = 0;
  int64_t update = 0;
  std::vector<AnchorCovariance> anchors;  // anchored trajectories only
};

// One square tile of the occupancy grid; the tile's lower-left corner is at
// (tile_x * width * resolution_m, tile_y * height * resolution_m); cells row-major with
// row 0 at the bottom; occupancy 0..100, -1 unknown (ROS map convention).
struct GridTile {
  int64_t utime = 0;
  int64_t update = 0;
  double resolution_m = 0.05;
  int32_t tile_x = 0;
  int32_t tile_y = 0;
  int32_t width = 0;
  int32_t height = 0;
  std::vector<int8_t> cells;
};

struct ServerStatus {
  int64_t utime = 0;
  int64_t instance_id = 0;  // random per server process start (> 0 online, 0 offline)
  int64_t update = 0;
  int32_t num_robots = 0;
  int32_t num_trajectories = 0;
  int32_t num_anchored = 0;
  int64_t keyframes = 0;
  int64_t encounters = 0;  // encounters added to the graph
  double last_update_ms = 0.0;
  int64_t bridged_gaps = 0;     // keyframe gaps bridged after waiting (lost keyframes)
  int64_t resend_requests = 0;  // resend requests published
  int64_t kernel_drops = 0;     // datagrams the kernel dropped on the server's sockets (-1: unseen)
  std::vector<std::pair<std::string, int64_t>> rejections;  // reason -> count (non-zero)
};

}  // namespace anchormap
