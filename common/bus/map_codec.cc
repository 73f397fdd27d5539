#include "common/bus/map_codec.h"

#include "anchormap/anchor_covariances_t.hpp"
#include "anchormap/grid_tile_t.hpp"
#include "anchormap/merged_map_chunk_t.hpp"
#include "anchormap/merged_map_header_t.hpp"
#include "anchormap/merged_map_t.hpp"
#include "anchormap/server_status_t.hpp"
#include "common/bus/codec_internal.h"

namespace anchormap {

using codec_internal::Encode;
using codec_internal::MatrixFromRowMajor;
using codec_internal::MatrixToRowMajor;
using codec_internal::PoseFromArray;
using codec_internal::PoseToArray;
using codec_internal::SafeDecode;
using codec_internal::Success;

namespace {

anchormap::encounter_link_t LinkToMessage(const EncounterLink& link) {
  anchormap::encounter_link_t out;
  out.robot_a = link.robot_a;
  out.robot_b = link.robot_b;
  out.trajectory_a = link.trajectory_a;
  out.index_a = link.index_a;
  out.trajectory_b = link.trajectory_b;
  out.index_b = link.index_b;
  out.kind = static_cast<int8_t>(link.kind);
  return out;
}

Result<EncounterLink> LinkFromMessage(const anchormap::encounter_link_t& link) {
  if (!IsValidConstraintKind(link.kind)) {
    return Status::Error(ErrorCode::kInvalidValue,
                         "encounter link kind " + std::to_string(link.kind) + " unknown");
  }
  return EncounterLink{link.robot_a,
                       link.trajectory_a,
                       link.index_a,
                       link.robot_b,
                       link.trajectory_b,
                       link.index_b,
                       static_cast<ConstraintKind>(link.kind)};
}

// Poses as the messages' rows of (x, y, theta), and back (the wire check saw the row sizes).
template <typename Rows>
void PosesToRows(const std::vector<Pose2>& poses, Rows* rows) {
  rows->clear();
  rows->reserve(poses.size());
  for (const Pose2& p : poses) rows->push_back({p.x(), p.y(), p.theta()});
}

template <typename Rows>
std::vector<Pose2> PosesFromRows(const Rows& rows) {
  std::vector<Pose2> poses;
  poses.reserve(rows.size());
  for (const auto& row : rows) poses.emplace_back(row[0], row[1], row[2]);
  return poses;
}

// Chunks a trajectory of `poses` poses has at `chunk_poses` a chunk.
int64_t NumChunks(int64_t poses, int64_t chunk_poses) {
  return chunk_poses > 0 ? (poses + chunk_poses - 1) / chunk_poses : 0;
}

}  // namespace

std::vector<uint8_t> EncodeMergedMap(const MergedMap& map) {
  anchormap::merged_map_t m;
  m.utime = map.utime;
  m.update = map.update;
  m.num_trajectories = static_cast<int32_t>(map.trajectories.size());
  for (const MergedTrajectory& t : map.trajectories) {
    anchormap::trajectory_t out;
    out.robot = t.robot;
    out.trajectory_id = t.trajectory_id;
    out.anchored = t.anchored;
    PoseToArray(t.T_global_local, out.anchor);
    out.num_poses = static_cast<int32_t>(t.poses.size());
    out.pose_utimes = t.pose_utimes;
    out.pose_utimes.resize(t.poses.size(), 0);
    PosesToRows(t.poses, &out.poses);
    m.trajectories.push_back(std::move(out));
  }
  m.num_encounters = static_cast<int32_t>(map.encounters.size());
  for (const EncounterLink& link : map.encounters) m.encounters.push_back(LinkToMessage(link));
  return Encode(m);
}

Result<MergedMap> DecodeMergedMap(const void* data, size_t size) {
  anchormap::merged_map_t m;
  if (Status p = SafeDecode(data, size, CheckMergedMapWire, &m); !p.ok()) return p;
  MergedMap map;
  map.utime = m.utime;
  map.update = m.update;
  for (const anchormap::trajectory_t& t : m.trajectories) {
    MergedTrajectory out;
    out.robot = t.robot;
    out.trajectory_id = t.trajectory_id;
    out.anchored = t.anchored;
    out.T_global_local = PoseFromArray(t.anchor);
    out.pose_utimes = t.pose_utimes;
    out.poses = PosesFromRows(t.poses);
    map.trajectories.push_back(std::move(out));
  }
  for (const anchormap::encounter_link_t& message : m.encounters) {
    Result<EncounterLink> link = LinkFromMessage(message);
    if (!link.ok()) return link.status();
    map.encounters.push_back(*link);
  }
  return Success(std::move(map));
}

std::vector<uint8_t> EncodeMergedMapHeader(const MergedMapHeader& header) {
  anchormap::merged_map_header_t m;
  m.utime = header.utime;
  m.update = header.update;
  m.chunk_poses = header.chunk_poses;
  m.num_trajectories = static_cast<int32_t>(header.trajectories.size());
  for (const MergedMapHeader::Trajectory& t : header.trajectories) {
    m.robots.push_back(t.robot);
    m.trajectory_ids.push_back(t.trajectory_id);
    m.anchored.push_back(t.anchored);
    m.anchors.push_back({t.T_global_local.x(), t.T_global_local.y(), t.T_global_local.theta()});
    m.num_poses.push_back(t.num_poses);
    m.chunk_versions.insert(m.chunk_versions.end(), t.chunk_versions.begin(),
                            t.chunk_versions.end());
  }
  m.num_chunks = static_cast<int32_t>(m.chunk_versions.size());
  m.num_encounters = header.num_encounters;
  return Encode(m);
}

Result<MergedMapHeader> DecodeMergedMapHeader(const void* data, size_t size) {
  anchormap::merged_map_header_t m;
  if (Status p = SafeDecode(data, size, CheckMergedMapHeaderWire, &m); !p.ok()) return p;
  if (m.chunk_poses <= 0) {
    return Status::Error(ErrorCode::kInvalidValue, "chunk_poses must be > 0");
  }
  if (m.num_encounters < 0) {
    return Status::Error(ErrorCode::kInvalidValue, "num_encounters must be >= 0");
  }
  MergedMapHeader header;
  header.utime = m.utime;
  header.update = m.update;
  header.chunk_poses = m.chunk_poses;
  header.num_encounters = m.num_encounters;
  size_t next_chunk = 0;
  for (int32_t i = 0; i < m.num_trajectories; ++i) {
    MergedMapHeader::Trajectory t;
    t.robot = m.robots[i];
    t.trajectory_id = m.trajectory_ids[i];
    t.anchored = m.anchored[i];
    t.T_global_local = Pose2(m.anchors[i][0], m.anchors[i][1], m.anchors[i][2]);
    t.num_poses = m.num_poses[i];
    if (t.num_poses < 0 || !t.T_global_local.IsFinite()) {
      return Status::Error(ErrorCode::kInvalidValue, "trajectory " + std::to_string(i) +
                                                         ": negative pose count or anchor not "
                                                         "finite");
    }
    const auto chunks = static_cast<size_t>(NumChunks(t.num_poses, m.chunk_poses));
    if (chunks > m.chunk_versions.size() - next_chunk) {
      return Status::Error(ErrorCode::kInvalidValue, "fewer chunk versions than poses need");
    }
    t.chunk_versions.assign(m.chunk_versions.begin() + static_cast<long>(next_chunk),
                            m.chunk_versions.begin() + static_cast<long>(next_chunk + chunks));
    next_chunk += chunks;
    header.trajectories.push_back(std::move(t));
  }
  if (next_chunk != m.chunk_versions.size()) {
    return Status::Error(ErrorCode::kInvalidValue, "more chunk versions than poses need");
  }
  return Success(std::move(header));
}

std::vector<uint8_t> EncodeMergedMapChunk(const MergedMapChunk& chunk) {
  anchormap::merged_map_chunk_t m;
  m.utime = chunk.utime;
  m.version = chunk.version;
  m.robot = chunk.robot;
  m.trajectory_id = chunk.trajectory_id;
  m.chunk_index = chunk.chunk_index;
  m.num_poses = static_cast<int32_t>(chunk.local_poses.size());
  m.pose_utimes = chunk.pose_utimes;
  m.pose_utimes.resize(chunk.local_poses.size(), 0);
  PosesToRows(chunk.local_poses, &m.local_poses);
  m.num_encounters = static_cast<int32_t>(chunk.encounters.size());
  for (const EncounterLink& link : chunk.encounters) m.encounters.push_back(LinkToMessage(link));
  m.encounter_positions = chunk.encounter_positions;
  m.encounter_positions.resize(chunk.encounters.size(), 0);
  return Encode(m);
}

Result<MergedMapChunk> DecodeMergedMapChunk(const void* data, size_t size) {
  anchormap::merged_map_chunk_t m;
  if (Status p = SafeDecode(data, size, CheckMergedMapChunkWire, &m); !p.ok()) return p;
  if (m.chunk_index < 0) {
    return Status::Error(ErrorCode::kInvalidValue, "chunk_index must be >= 0");
  }
  MergedMapChunk chunk;
  chunk.utime = m.utime;
  chunk.version = m.version;
  chunk.robot = m.robot;
  chunk.trajectory_id = m.trajectory_id;
  chunk.chunk_index = m.chunk_index;
  chunk.pose_utimes = m.pose_utimes;
  chunk.local_poses = PosesFromRows(m.local_poses);
  for (size_t i = 0; i < m.encounters.size(); ++i) {
    Result<EncounterLink> link = LinkFromMessage(m.encounters[i]);
    if (!link.ok()) return link.status();
    if (m.encounter_positions[i] < 0) {
      return Status::Error(ErrorCode::kInvalidValue, "encounter position must be >= 0");
    }
    chunk.encounters.push_back(*link);
  }
  chunk.encounter_positions = m.encounter_positions;
  return Success(std::move(chunk));
}

std::vector<uint8_t> EncodeAnchorCovariances(const AnchorCovariances& anchors) {
  anchormap::anchor_covariances_t m;
  m.utime = anchors.utime;
  m.update = anchors.update;
  m.num_anchors = static_cast<int32_t>(anchors.anchors.size());
  for (const AnchorCovariance& a : anchors.anchors) {
    anchormap::anchor_covariance_t out;
    out.robot = a.robot;
    out.trajectory_id = a.trajectory_id;
    PoseToArray(a.T_global_local, out.anchor);
    MatrixToRowMajor(a.covariance, out.covariance);
    m.anchors.push_back(std::move(out));
  }
  return Encode(m);
}

Result<AnchorCovariances> DecodeAnchorCovariances(const void* data, size_t size) {
  anchormap::anchor_covariances_t m;
  if (Status p = SafeDecode(data, size, CheckAnchorCovariancesWire, &m); !p.ok()) {
    return p;
  }
  AnchorCovariances anchors;
  anchors.utime = m.utime;
  anchors.update = m.update;
  for (const anchormap::anchor_covariance_t& a : m.anchors) {
    anchors.anchors.push_back(
        {a.robot, a.trajectory_id, PoseFromArray(a.anchor), MatrixFromRowMajor(a.covariance)});
  }
  return Success(std::move(anchors));
}

std::vector<uint8_t> EncodeGridTile(const GridTile& tile) {
  anchormap::grid_tile_t m;
  m.utime = tile.utime;
  m.update = tile.update;
  m.resolution = tile.resolution_m;
  m.tile_x = tile.tile_x;
  m.tile_y = tile.tile_y;
  m.width = tile.width;
  m.height = tile.height;
  m.cells.assign(static_cast<size_t>(tile.height),
                 std::vector<int8_t>(static_cast<size_t>(tile.width), -1));
  for (int32_t r = 0; r < tile.height; ++r) {
    for (int32_t c = 0; c < tile.width; ++c) {
      const size_t i =
          static_cast<size_t>(r) * static_cast<size_t>(tile.width) + static_cast<size_t>(c);
      if (i < tile.cells.size()) m.cells[r][c] = tile.cells[i];
    }
  }
  return Encode(m);
}

Result<GridTile> DecodeGridTile(const void* data, size_t size) {
  anchormap::grid_tile_t m;
  if (Status p = SafeDecode(data, size, CheckGridTileWire, &m); !p.ok()) return p;
  GridTile tile;
  tile.utime = m.utime;
  tile.update = m.update;
  tile.resolution_m = m.resolution;
  tile.tile_x = m.tile_x;
  tile.tile_y = m.tile_y;
  tile.width = m.width;
  tile.height = m.height;
  for (const auto& row : m.cells) tile.cells.insert(tile.cells.end(), row.begin(), row.end());
  return Success(std::move(tile));
}

std::vector<uint8_t> EncodeServerStatus(const ServerStatus& s) {
  anchormap::server_status_t m;
  m.utime = s.utime;
  m.instance_id = s.instance_id;
  m.update = s.update;
  m.num_robots = s.num_robots;
  m.num_trajectories = s.num_trajectories;
  m.num_anchored = s.num_anchored;
  m.keyframes = s.keyframes;
  m.encounters = s.encounters;
  m.last_update_ms = s.last_update_ms;
  m.bridged_gaps = s.bridged_gaps;
  m.resend_requests = s.resend_requests;
  m.kernel_drops = s.kernel_drops;
  m.num_reasons = static_cast<int32_t>(s.rejections.size());
  for (const auto& [reason, count] : s.rejections) {
    m.rejection_reasons.push_back(reason);
    m.rejection_counts.push_back(count);
  }
  return Encode(m);
}

Result<ServerStatus> DecodeServerStatus(const void* data, size_t size) {
  anchormap::server_status_t m;
  if (Status p = SafeDecode(data, size, CheckServerStatusWire, &m); !p.ok()) return p;
  if (m.kernel_drops < -1) {
    return Status::Error(ErrorCode::kInvalidValue,
                         "kernel drop count " + std::to_string(m.kernel_drops) + " below -1");
  }
  if (m.instance_id < 0) {
    return Status::Error(ErrorCode::kInvalidValue,
                         "negative server instance id " + std::to_string(m.instance_id));
  }
  ServerStatus s;
  s.utime = m.utime;
  s.instance_id = m.instance_id;
  s.update = m.update;
  s.num_robots = m.num_robots;
  s.num_trajectories = m.num_trajectories;
  s.num_anchored = m.num_anchored;
  s.keyframes = m.keyframes;
  s.encounters = m.encounters;
  s.last_update_ms = m.last_update_ms;
  s.bridged_gaps = m.bridged_gaps;
  s.resend_requests = m.resend_requests;
  s.kernel_drops = m.kernel_drops;
  for (size_t i = 0; i < m.rejection_reasons.size(); ++i) {
    s.rejections.emplace_back(m.rejection_reasons[i], m.rejection_counts[i]);
  }
  return Success(std::move(s));
}

}  // namespace anchormap
