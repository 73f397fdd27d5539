#pragma once
// Wire bytes <-> validated plain values (common/types/), the only place where anchormap's
// values meet LCM-generated types. Decoding never throws and never trusts a length field:
// sizes are checked against the buffer before anything is allocated, numbers must be
// finite, covariances symmetric positive definite, names non-empty. Every failure is a
// ErrorCode with a one-line detail, for the caller's RejectCounter.
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
#include "common/util/reject_counter.h"

namespace anchormap {

// A decoded value, or why there is none.
template <typename T>
struct Decoded {
  std::optional<T> value;
  ErrorCode reason = ErrorCode::kDecodeFailed;  // meaningful when !value
  std::string detail;
  bool ok() const { return value.has_value(); }
  static Decoded Fail(ErrorCode why, std::string text) {
    Decoded d;
    d.reason = why;
    d.detail = std::move(text);
    return d;
  }
};

// Sanity limits for decoded messages (a scan of more beams than this is "absurd").
struct CodecLimits {
  static constexpr int32_t kMaxRanges = 10000;
  static constexpr size_t kMaxNameLength = 64;
  static constexpr int32_t kMaxTrajectories = 10000;
  static constexpr int32_t kMaxPosesPerTrajectory = 10000000;
  static constexpr int32_t kMaxTileCells = 4096 * 4096;
};

// bot_core.pose_t: position (x, y, -), orientation quaternion (w, x, y, z) of a yaw.
Decoded<OdometrySample> DecodeOdometry(const void* data, size_t size);
std::vector<uint8_t> EncodeOdometry(const OdometrySample& sample);

// bot_core.planar_lidar_t. The wire type carries no max range nor mounting pose: the
// caller supplies them (agent flags). Non-finite ranges are refused.
Decoded<LaserScan> DecodeLaser(const void* data, size_t size, float max_range_m,
                               const Pose2& T_body_sensor);
std::vector<uint8_t> EncodeLaser(const LaserScan& scan);

// anchormap.keyframe_t
Decoded<Keyframe> DecodeKeyframe(const void* data, size_t size);
std::vector<uint8_t> EncodeKeyframe(const Keyframe& keyframe);

// anchormap.encounter_t
Decoded<Encounter> DecodeEncounter(const void* data, size_t size);
std::vector<uint8_t> EncodeEncounter(const Encounter& encounter);

// Quaternion (w, x, y, z) of a rotation by `yaw` about z, and back (the yaw of any
// quaternion, i.e. its heading after projecting onto the plane).
void YawToQuaternion(double yaw, double quaternion_wxyz[4]);
double QuaternionToYaw(const double quaternion_wxyz[4]);

}  // namespace anchormap
