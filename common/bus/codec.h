#pragma once
// Wire bytes <-> validated plain values (common/types/), the only place where anchormap's
// values meet LCM-generated types. Decoding never throws and never trusts a length field:
// sizes are checked against the buffer before anything is allocated, numbers must be
// finite, covariances symmetric positive definite, names non-empty. Every failure is a
// Status (an ErrorCode and a one-line message) for the caller's RejectCounter.
// This header includes no LCM header, so callers stay free of the bus.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "common/geometry/pose2.h"
#include "common/types/encounter.h"
#include "common/types/keyframe.h"
#include "common/types/laser_scan.h"
#include "common/types/odometry.h"
#include "common/util/status.h"

namespace anchormap {

// Sanity limits for decoded messages (a scan of more beams than this is "absurd").
struct CodecLimits {
  static constexpr int32_t kMaxRanges = 10000;
  static constexpr size_t kMaxNameLength = 64;
  static constexpr int32_t kMaxTrajectories = 10000;
  static constexpr int32_t kMaxPosesPerTrajectory = 10000000;
  static constexpr int32_t kMaxTileCells = 4096 * 4096;
  // Times beyond this (about year 5138) are refused: far from INT64_MAX, so that adding
  // periods and windows to a data time never overflows.
  static constexpr int64_t kMaxUtime = 100'000'000'000'000'000;
};

// bot_core.pose_t: position (x, y, -), orientation quaternion (w, x, y, z) of a yaw.
Result<OdometrySample> DecodeOdometry(const void* data, size_t size);
std::vector<uint8_t> EncodeOdometry(const OdometrySample& sample);

// bot_core.planar_lidar_t. The wire type carries no max range nor mounting pose: they
// stay 0 and identity here, and the agent sets them from its flags (Agent::OnScan).
// Non-finite ranges are refused.
Result<LaserScan> DecodeLaser(const void* data, size_t size);
std::vector<uint8_t> EncodeLaser(const LaserScan& scan);

// anchormap.keyframe_t; also the layout before encounters_relayed (anchormap.keyframe_v1_t,
// in journals written then), decoded with encounters_relayed = 0 (it reveals nothing).
Result<Keyframe> DecodeKeyframe(const void* data, size_t size);
std::vector<uint8_t> EncodeKeyframe(const Keyframe& keyframe);

// anchormap.encounter_t
Result<Encounter> DecodeEncounter(const void* data, size_t size);
std::vector<uint8_t> EncodeEncounter(const Encounter& encounter);

}  // namespace anchormap
