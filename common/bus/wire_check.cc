#include "common/bus/wire_check.h"

#include "anchormap/anchor_covariances_t.hpp"
#include "anchormap/encounter_t.hpp"
#include "anchormap/grid_tile_t.hpp"
#include "anchormap/keyframe_t.hpp"
#include "anchormap/keyframe_v1_t.hpp"
#include "anchormap/merged_map_chunk_t.hpp"
#include "anchormap/merged_map_header_t.hpp"
#include "anchormap/merged_map_t.hpp"
#include "anchormap/server_status_t.hpp"
#include "bot_core/planar_lidar_t.hpp"
#include "bot_core/pose_t.hpp"
#include "common/bus/codec.h"

namespace anchormap {
namespace {

#define WIRE_SKIP(cursor, n, where) \
  if (!(cursor).Skip(n)) return TruncatedAt(where)
#define WIRE_TRY(expr) \
  if (Status problem = (expr); !problem.ok()) return problem

}  // namespace

Status TruncatedAt(const char* field) {
  return Status::Error(ErrorCode::kDecodeFailed, std::string("truncated message at ") + field);
}

Status WireCursor::SkipField(size_t n, const char* field) {
  return Skip(n) ? Status::Ok() : TruncatedAt(field);
}

bool WireCursor::Skip(size_t n) {
  if (n > remaining()) return false;
  position_ += n;
  return true;
}

bool WireCursor::ReadInt32(int32_t* value) {
  if (remaining() < 4) return false;
  const uint8_t* b = bytes_ + position_;
  *value = static_cast<int32_t>((uint32_t{b[0]} << 24) | (uint32_t{b[1]} << 16) |
                                (uint32_t{b[2]} << 8) | uint32_t{b[3]});
  position_ += 4;
  return true;
}

bool WireCursor::ReadUint64(uint64_t* value) {
  if (remaining() < 8) return false;
  uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v = (v << 8) | bytes_[position_ + i];
  *value = v;
  position_ += 8;
  return true;
}

Status WireCursor::SkipString(const char* field, size_t max_length) {
  int32_t length_with_nul = 0;
  if (!ReadInt32(&length_with_nul)) return TruncatedAt(field);
  if (length_with_nul < 1) {
    return Status::Error(ErrorCode::kDecodeFailed,
                         std::string(field) + " has an invalid string length");
  }
  if (static_cast<size_t>(length_with_nul) - 1 > max_length) {
    return Status::Error(ErrorCode::kAbsurdSize,
                         std::string(field) + " is " + std::to_string(length_with_nul - 1) +
                             " bytes long (limit " + std::to_string(max_length) + ")");
  }
  if (!Skip(static_cast<size_t>(length_with_nul))) return TruncatedAt(field);
  // lcm-gen's decode drops the last byte without looking: it must be the terminator. An
  // earlier NUL would survive decoding but not encoding (which measures with strlen while
  // getEncodedSize counts every byte: the re-encoded message would end in stray zeros).
  const uint8_t* text = bytes_ + position_ - length_with_nul;
  if (text[length_with_nul - 1] != 0) {
    return Status::Error(ErrorCode::kDecodeFailed, std::string(field) + " is not NUL-terminated");
  }
  for (int32_t i = 0; i + 1 < length_with_nul; ++i) {
    if (text[i] == 0) {
      return Status::Error(ErrorCode::kDecodeFailed, std::string(field) + " has a NUL inside");
    }
  }
  return Status::Ok();
}

Status WireCursor::ReadCount(const char* field, int32_t max_count, size_t min_element_bytes,
                             int32_t* count) {
  if (!ReadInt32(count)) return TruncatedAt(field);
  if (*count < 0 || *count > max_count) {
    return Status::Error(ErrorCode::kAbsurdSize, std::string(field) + " = " +
                                                     std::to_string(*count) + " (limit " +
                                                     std::to_string(max_count) + ")");
  }
  if (static_cast<size_t>(*count) * min_element_bytes > remaining()) return TruncatedAt(field);
  return Status::Ok();
}

Status CheckPlanarLidarWire(const void* data, size_t size) {
  WireCursor c(data, size);
  WIRE_TRY(CheckFingerprint<bot_core::planar_lidar_t>(&c));
  WIRE_SKIP(c, 8, "utime");
  int32_t n = 0;
  WIRE_TRY(c.ReadCount("nranges", CodecLimits::kMaxRanges, 4, &n));
  WIRE_SKIP(c, 4 * static_cast<size_t>(n), "ranges");
  WIRE_TRY(c.ReadCount("nintensities", CodecLimits::kMaxRanges, 4, &n));
  WIRE_SKIP(c, 4 * static_cast<size_t>(n), "intensities");
  WIRE_SKIP(c, 8, "rad0/radstep");
  return Status::Ok();
}

Status CheckPoseWire(const void* data, size_t size) {
  WireCursor c(data, size);
  WIRE_TRY(CheckFingerprint<bot_core::pose_t>(&c));
  WIRE_SKIP(c, 8 + 8 * (3 + 3 + 4 + 3 + 3), "pose fields");
  return Status::Ok();
}

namespace {
// The fields after the fingerprint; `relay_count_bytes` is 4 in keyframe_t (the
// encounters_relayed after seq), 0 in keyframe_v1_t.
Status CheckKeyframeFields(WireCursor* c, size_t relay_count_bytes) {
  WIRE_SKIP(*c, 8, "utime");
  WIRE_TRY(c->SkipString("robot", CodecLimits::kMaxNameLength));
  WIRE_SKIP(*c, 8 + 4 + relay_count_bytes + 8 * (3 + 3 + 9 + 3) + 4 * 3, "keyframe fields");
  int32_t n = 0;
  WIRE_TRY(c->ReadCount("nranges", CodecLimits::kMaxRanges, 4, &n));
  WIRE_SKIP(*c, 4 * static_cast<size_t>(n), "ranges");
  return Status::Ok();
}
}  // namespace

Status CheckKeyframeWire(const void* data, size_t size) {
  WireCursor c(data, size);
  WIRE_TRY(CheckFingerprint<anchormap::keyframe_t>(&c));
  return CheckKeyframeFields(&c, 4);
}

Status CheckKeyframeV1Wire(const void* data, size_t size) {
  WireCursor c(data, size);
  WIRE_TRY(CheckFingerprint<anchormap::keyframe_v1_t>(&c));
  return CheckKeyframeFields(&c, 0);
}

Status CheckEncounterWire(const void* data, size_t size) {
  WireCursor c(data, size);
  WIRE_TRY(CheckFingerprint<anchormap::encounter_t>(&c));
  WIRE_SKIP(c, 8, "utime");
  WIRE_TRY(c.SkipString("observer", CodecLimits::kMaxNameLength));
  WIRE_SKIP(c, 8, "observer_trajectory_id");
  WIRE_TRY(c.SkipString("observed", CodecLimits::kMaxNameLength));
  WIRE_SKIP(c, 8 * (3 + 9), "relative_pose/covariance");
  WIRE_SKIP(c, 4, "seq");
  return Status::Ok();
}

namespace {
// The encounter links of a merged_map_t or merged_map_chunk_t.
Status SkipEncounterLinks(WireCursor* c, int32_t encounters) {
  for (int32_t e = 0; e < encounters; ++e) {
    WIRE_TRY(c->SkipString("robot_a", CodecLimits::kMaxNameLength));
    WIRE_TRY(c->SkipField(12, "trajectory_a/index_a"));
    WIRE_TRY(c->SkipString("robot_b", CodecLimits::kMaxNameLength));
    WIRE_TRY(c->SkipField(12 + 1, "trajectory_b/index_b/kind"));
  }
  return Status::Ok();
}
}  // namespace

Status CheckMergedMapWire(const void* data, size_t size) {
  WireCursor c(data, size);
  WIRE_TRY(CheckFingerprint<anchormap::merged_map_t>(&c));
  WIRE_SKIP(c, 16, "utime/update");
  int32_t trajectories = 0;
  // A trajectory takes at least 4 + 1 + 8 + 1 + 24 + 4 bytes.
  WIRE_TRY(c.ReadCount("num_trajectories", CodecLimits::kMaxTrajectories, 42, &trajectories));
  for (int32_t t = 0; t < trajectories; ++t) {
    WIRE_TRY(c.SkipString("robot", CodecLimits::kMaxNameLength));
    WIRE_SKIP(c, 8 + 1 + 24, "trajectory fields");
    int32_t poses = 0;
    WIRE_TRY(c.ReadCount("num_poses", CodecLimits::kMaxPosesPerTrajectory, 32, &poses));
    WIRE_SKIP(c, 32 * static_cast<size_t>(poses), "poses");
  }
  int32_t encounters = 0;
  // A link takes at least 2 * (4 + 1 + 8 + 4) + 1 bytes.
  WIRE_TRY(c.ReadCount("num_encounters", CodecLimits::kMaxPosesPerTrajectory, 35, &encounters));
  return SkipEncounterLinks(&c, encounters);
}

Status CheckMergedMapHeaderWire(const void* data, size_t size) {
  WireCursor c(data, size);
  WIRE_TRY(CheckFingerprint<anchormap::merged_map_header_t>(&c));
  WIRE_SKIP(c, 16 + 4, "utime/update/chunk_poses");
  int32_t trajectories = 0;
  // A trajectory takes at least 5 (robot) + 8 + 1 + 24 + 4 bytes.
  WIRE_TRY(c.ReadCount("num_trajectories", CodecLimits::kMaxTrajectories, 42, &trajectories));
  for (int32_t t = 0; t < trajectories; ++t) {
    WIRE_TRY(c.SkipString("robots", CodecLimits::kMaxNameLength));
  }
  WIRE_SKIP(c, (8 + 1 + 24 + 4) * static_cast<size_t>(trajectories), "trajectory fields");
  int32_t chunks = 0;
  WIRE_TRY(c.ReadCount("num_chunks", CodecLimits::kMaxPosesPerTrajectory, 8, &chunks));
  WIRE_SKIP(c, 8 * static_cast<size_t>(chunks), "chunk_versions");
  WIRE_SKIP(c, 4, "num_encounters");
  return Status::Ok();
}

Status CheckMergedMapChunkWire(const void* data, size_t size) {
  WireCursor c(data, size);
  WIRE_TRY(CheckFingerprint<anchormap::merged_map_chunk_t>(&c));
  WIRE_SKIP(c, 16, "utime/version");
  WIRE_TRY(c.SkipString("robot", CodecLimits::kMaxNameLength));
  WIRE_SKIP(c, 8 + 4, "trajectory_id/chunk_index");
  int32_t poses = 0;
  WIRE_TRY(c.ReadCount("num_poses", CodecLimits::kMaxPosesPerTrajectory, 32, &poses));
  WIRE_SKIP(c, 32 * static_cast<size_t>(poses), "poses");
  int32_t encounters = 0;
  // A link takes at least 2 * (4 + 1 + 8 + 4) + 1 bytes, and a position 4.
  WIRE_TRY(c.ReadCount("num_encounters", CodecLimits::kMaxPosesPerTrajectory, 39, &encounters));
  WIRE_TRY(SkipEncounterLinks(&c, encounters));
  WIRE_SKIP(c, 4 * static_cast<size_t>(encounters), "encounter_positions");
  return Status::Ok();
}

Status CheckAnchorCovariancesWire(const void* data, size_t size) {
  WireCursor c(data, size);
  WIRE_TRY(CheckFingerprint<anchormap::anchor_covariances_t>(&c));
  WIRE_SKIP(c, 16, "utime/update");
  int32_t anchors = 0;
  WIRE_TRY(c.ReadCount("num_anchors", CodecLimits::kMaxTrajectories, 4 + 1 + 8 + 96, &anchors));
  for (int32_t a = 0; a < anchors; ++a) {
    WIRE_TRY(c.SkipString("robot", CodecLimits::kMaxNameLength));
    WIRE_SKIP(c, 8 + 24 + 72, "anchor fields");
  }
  return Status::Ok();
}

Status CheckGridTileWire(const void* data, size_t size) {
  WireCursor c(data, size);
  WIRE_TRY(CheckFingerprint<anchormap::grid_tile_t>(&c));
  WIRE_SKIP(c, 8 + 8 + 8 + 4 + 4, "tile header");
  int32_t width = 0, height = 0;
  WIRE_TRY(c.ReadCount("width", 4096, 0, &width));
  WIRE_TRY(c.ReadCount("height", 4096, 0, &height));
  const size_t cells = static_cast<size_t>(width) * static_cast<size_t>(height);
  WIRE_SKIP(c, cells, "cells");
  return Status::Ok();
}

Status CheckServerStatusWire(const void* data, size_t size) {
  WireCursor c(data, size);
  WIRE_TRY(CheckFingerprint<anchormap::server_status_t>(&c));
  WIRE_SKIP(c, 8 + 8 + 8 + 12 + 8 + 8 + 8 + 8 + 8 + 8, "status fields");
  int32_t reasons = 0;
  WIRE_TRY(c.ReadCount("num_reasons", 1000, 13, &reasons));
  for (int32_t r = 0; r < reasons; ++r) WIRE_TRY(c.SkipString("reason", 256));
  WIRE_SKIP(c, 8 * static_cast<size_t>(reasons), "rejection_counts");
  return Status::Ok();
}

}  // namespace anchormap
