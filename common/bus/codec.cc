#include "common/bus/codec.h"

#include <cmath>
#include <exception>

#include "anchormap/anchor_covariances_t.hpp"
#include "anchormap/encounter_t.hpp"
#include "anchormap/grid_tile_t.hpp"
#include "anchormap/keyframe_t.hpp"
#include "anchormap/keyframe_v1_t.hpp"
#include "anchormap/merged_map_t.hpp"
#include "anchormap/server_status_t.hpp"
#include "bot_core/planar_lidar_t.hpp"
#include "bot_core/pose_t.hpp"
#include "common/bus/codec_internal.h"
#include "common/bus/wire_check.h"
#include "common/geometry/covariance.h"

namespace anchormap {

using codec_internal::AllFinite;
using codec_internal::CheckName;
using codec_internal::CheckRanges;
using codec_internal::CheckScanGeometry;
using codec_internal::CheckUtime;
using codec_internal::Encode;
using codec_internal::MatrixFromRowMajor;
using codec_internal::MatrixToRowMajor;
using codec_internal::PoseFromArray;
using codec_internal::PoseToArray;
using codec_internal::SafeDecode;
using codec_internal::Success;

Result<OdometrySample> DecodeOdometry(const void* data, size_t size) {
  bot_core::pose_t message;
  if (Status p = SafeDecode(data, size, CheckPoseWire, &message); !p.ok()) return p;
  if (!AllFinite(message.pos, 3) || !AllFinite(message.orientation, 4)) {
    return Status::Error(ErrorCode::kNotFinite, "position or orientation");
  }
  const double norm = std::sqrt(message.orientation[0] * message.orientation[0] +
                                message.orientation[1] * message.orientation[1] +
                                message.orientation[2] * message.orientation[2] +
                                message.orientation[3] * message.orientation[3]);
  if (std::abs(norm - 1.0) > 0.1) {
    return Status::Error(ErrorCode::kInvalidValue, "orientation is not a unit quaternion");
  }
  if (Status p = CheckUtime(message.utime); !p.ok()) return p;
  OdometrySample sample;
  sample.utime = message.utime;
  sample.T_odom_body = Pose2(message.pos[0], message.pos[1],
                             YawOfQuaternion(message.orientation[0], message.orientation[1],
                                             message.orientation[2], message.orientation[3]));
  return Success(sample);
}

std::vector<uint8_t> EncodeOdometry(const OdometrySample& sample) {
  bot_core::pose_t message{};
  message.utime = sample.utime;
  message.pos[0] = sample.T_odom_body.x();
  message.pos[1] = sample.T_odom_body.y();
  QuaternionOfYaw(sample.T_odom_body.theta(), &message.orientation[0], &message.orientation[1],
                  &message.orientation[2], &message.orientation[3]);
  return Encode(message);
}

Result<LaserScan> DecodeLaser(const void* data, size_t size) {
  bot_core::planar_lidar_t message;
  if (Status p = SafeDecode(data, size, CheckPlanarLidarWire, &message); !p.ok()) return p;
  if (message.nranges < 1) return Status::Error(ErrorCode::kInvalidValue, "no ranges");
  if (Status p = CheckUtime(message.utime); !p.ok()) return p;
  if (Status p = CheckScanGeometry(message.rad0, message.radstep, message.ranges.size()); !p.ok()) {
    return p;
  }
  if (Status p = CheckRanges(message.ranges); !p.ok()) return p;
  LaserScan scan;
  scan.utime = message.utime;
  scan.rad0 = message.rad0;
  scan.radstep = message.radstep;
  scan.ranges = std::move(message.ranges);
  return Success(std::move(scan));
}

std::vector<uint8_t> EncodeLaser(const LaserScan& scan) {
  bot_core::planar_lidar_t message;
  message.utime = scan.utime;
  message.nranges = static_cast<int32_t>(scan.ranges.size());
  message.ranges = scan.ranges;
  message.nintensities = 0;
  message.rad0 = scan.rad0;
  message.radstep = scan.radstep;
  return Encode(message);
}

namespace {

// True when the message starts with the fingerprint of T (an lcm-gen type).
template <typename T>
bool HasFingerprint(const void* data, size_t size) {
  WireCursor cursor(data, size);
  uint64_t hash = 0;
  return cursor.ReadUint64(&hash) && hash == static_cast<uint64_t>(T::getHash());
}

// keyframe_t and keyframe_v1_t (before encounters_relayed) share every other field.
template <typename Message>
Result<Keyframe> ValidKeyframe(Message& m, int32_t encounters_relayed) {
  if (Status p = CheckName(m.robot, "robot"); !p.ok()) return p;
  if (m.seq < 0) return Status::Error(ErrorCode::kBadSequence, "negative seq");
  if (encounters_relayed < 0) {
    return Status::Error(ErrorCode::kBadSequence, "negative encounters_relayed");
  }
  if (Status p = CheckUtime(m.utime); !p.ok()) return p;
  if (!AllFinite(m.pose, 3) || !AllFinite(m.T_previous_this, 3) ||
      !AllFinite(m.T_previous_this_covariance, 9) || !AllFinite(m.sensor_offset, 3) ||
      !std::isfinite(m.max_range)) {
    return Status::Error(ErrorCode::kNotFinite,
                         "pose, T_previous_this, its covariance or sensor_offset");
  }
  const Eigen::Matrix3d covariance = MatrixFromRowMajor(m.T_previous_this_covariance);
  if (Status why = CheckSymmetricPositiveDefinite(covariance); !why.ok()) {
    return Status::Error(why.code(), "T_previous_this_covariance: " + why.message());
  }
  if (!(m.max_range > 0.0f)) return Status::Error(ErrorCode::kInvalidValue, "max_range <= 0");
  if (Status p = CheckScanGeometry(m.rad0, m.radstep, m.ranges.size()); !p.ok()) return p;
  if (Status p = CheckRanges(m.ranges); !p.ok()) return p;

  Keyframe k;
  k.robot = m.robot;
  k.trajectory_id = m.trajectory_id;
  k.seq = m.seq;
  k.encounters_relayed = encounters_relayed;
  k.utime = m.utime;
  k.T_local_pose = PoseFromArray(m.pose);
  k.T_previous_this = PoseFromArray(m.T_previous_this);
  k.T_previous_this_covariance = covariance;
  k.scan.utime = m.utime;
  k.scan.rad0 = m.rad0;
  k.scan.radstep = m.radstep;
  k.scan.max_range = m.max_range;
  k.scan.ranges = std::move(m.ranges);
  k.scan.T_body_sensor = PoseFromArray(m.sensor_offset);
  return Success(std::move(k));
}

}  // namespace

Result<Keyframe> DecodeKeyframe(const void* data, size_t size) {
  if (HasFingerprint<anchormap::keyframe_v1_t>(data, size)) {
    // The layout before encounters_relayed (journals written then): it reveals nothing.
    anchormap::keyframe_v1_t m;
    if (Status p = SafeDecode(data, size, CheckKeyframeV1Wire, &m); !p.ok()) return p;
    return ValidKeyframe(m, 0);
  }
  anchormap::keyframe_t m;
  if (Status p = SafeDecode(data, size, CheckKeyframeWire, &m); !p.ok()) return p;
  return ValidKeyframe(m, m.encounters_relayed);
}

std::vector<uint8_t> EncodeKeyframe(const Keyframe& k) {
  anchormap::keyframe_t m;
  m.utime = k.utime;
  m.robot = k.robot;
  m.trajectory_id = k.trajectory_id;
  m.seq = k.seq;
  m.encounters_relayed = k.encounters_relayed;
  PoseToArray(k.T_local_pose, m.pose);
  PoseToArray(k.T_previous_this, m.T_previous_this);
  MatrixToRowMajor(k.T_previous_this_covariance, m.T_previous_this_covariance);
  PoseToArray(k.scan.T_body_sensor, m.sensor_offset);
  m.rad0 = k.scan.rad0;
  m.radstep = k.scan.radstep;
  m.max_range = k.scan.max_range;
  m.nranges = static_cast<int32_t>(k.scan.ranges.size());
  m.ranges = k.scan.ranges;
  return Encode(m);
}

Result<Encounter> DecodeEncounter(const void* data, size_t size) {
  anchormap::encounter_t m;
  if (Status p = SafeDecode(data, size, CheckEncounterWire, &m); !p.ok()) return p;
  if (Status p = CheckName(m.observer, "observer"); !p.ok()) return p;
  if (Status p = CheckName(m.observed, "observed"); !p.ok()) return p;
  if (m.observer == m.observed) {
    return Status::Error(ErrorCode::kSelfEncounter, m.observer + " observed itself");
  }
  if (Status p = CheckUtime(m.utime); !p.ok()) return p;
  if (m.seq < -1) return Status::Error(ErrorCode::kBadSequence, "encounter seq < -1");
  if (!AllFinite(m.relative_pose, 3) || !AllFinite(m.covariance, 9)) {
    return Status::Error(ErrorCode::kNotFinite, "relative pose or covariance");
  }
  const Eigen::Matrix3d covariance = MatrixFromRowMajor(m.covariance);
  if (Status why = CheckSymmetricPositiveDefinite(covariance); !why.ok()) {
    return Status::Error(why.code(), "covariance: " + why.message());
  }
  Encounter e;
  e.utime = m.utime;
  e.observer = m.observer;
  e.observer_trajectory_id = m.observer_trajectory_id;
  e.observed = m.observed;
  e.T_observer_observed = PoseFromArray(m.relative_pose);
  e.covariance = covariance;
  e.seq = m.seq;
  return Success(std::move(e));
}

std::vector<uint8_t> EncodeEncounter(const Encounter& e) {
  anchormap::encounter_t m;
  m.utime = e.utime;
  m.observer = e.observer;
  m.observer_trajectory_id = e.observer_trajectory_id;
  m.observed = e.observed;
  PoseToArray(e.T_observer_observed, m.relative_pose);
  MatrixToRowMajor(e.covariance, m.covariance);
  m.seq = e.seq;
  return Encode(m);
}

}  // namespace anchormap
