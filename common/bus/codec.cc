#include "common/bus/codec.h"

#include <cmath>
#include <exception>

#include "anchormap/anchor_covariances_t.hpp"
#include "anchormap/encounter_t.hpp"
#include "anchormap/grid_tile_t.hpp"
#include "anchormap/keyframe_t.hpp"
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
using codec_internal::Encode;
using codec_internal::FromProblem;
using codec_internal::MatrixFromRowMajor;
using codec_internal::MatrixToRowMajor;
using codec_internal::PoseFromArray;
using codec_internal::PoseToArray;
using codec_internal::SafeDecode;
using codec_internal::Success;

void YawToQuaternion(double yaw, double q[4]) {
  q[0] = std::cos(yaw / 2.0);
  q[1] = 0.0;
  q[2] = 0.0;
  q[3] = std::sin(yaw / 2.0);
}

double QuaternionToYaw(const double q[4]) {
  const double w = q[0], x = q[1], y = q[2], z = q[3];
  return std::atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z));
}

Decoded<OdometrySample> DecodeOdometry(const void* data, size_t size) {
  bot_core::pose_t message;
  if (auto p = SafeDecode(data, size, CheckPoseWire, &message))
    return FromProblem<OdometrySample>(*p);
  if (!AllFinite(message.pos, 3) || !AllFinite(message.orientation, 4)) {
    return Decoded<OdometrySample>::Fail(ErrorCode::kNotFinite, "position or orientation");
  }
  const double norm = std::sqrt(message.orientation[0] * message.orientation[0] +
                                message.orientation[1] * message.orientation[1] +
                                message.orientation[2] * message.orientation[2] +
                                message.orientation[3] * message.orientation[3]);
  if (std::abs(norm - 1.0) > 0.1) {
    return Decoded<OdometrySample>::Fail(ErrorCode::kInvalidValue,
                                         "orientation is not a unit quaternion");
  }
  if (message.utime < 0) {
    return Decoded<OdometrySample>::Fail(ErrorCode::kInvalidValue, "negative utime");
  }
  OdometrySample sample;
  sample.utime = message.utime;
  sample.T_odom_body = Pose2(message.pos[0], message.pos[1], QuaternionToYaw(message.orientation));
  return Success(sample);
}

std::vector<uint8_t> EncodeOdometry(const OdometrySample& sample) {
  bot_core::pose_t message{};
  message.utime = sample.utime;
  message.pos[0] = sample.T_odom_body.x();
  message.pos[1] = sample.T_odom_body.y();
  YawToQuaternion(sample.T_odom_body.theta(), message.orientation);
  return Encode(message);
}

Decoded<LaserScan> DecodeLaser(const void* data, size_t size, float max_range_m,
                               const Pose2& T_body_sensor) {
  bot_core::planar_lidar_t message;
  if (auto p = SafeDecode(data, size, CheckPlanarLidarWire, &message))
    return FromProblem<LaserScan>(*p);
  if (message.nranges < 1)
    return Decoded<LaserScan>::Fail(ErrorCode::kInvalidValue, "no ranges");
  if (message.utime < 0)
    return Decoded<LaserScan>::Fail(ErrorCode::kInvalidValue, "negative utime");
  if (auto p = CheckScanGeometry(message.rad0, message.radstep, message.ranges.size())) {
    return FromProblem<LaserScan>(*p);
  }
  if (auto p = CheckRanges(message.ranges)) return FromProblem<LaserScan>(*p);
  LaserScan scan;
  scan.utime = message.utime;
  scan.rad0 = message.rad0;
  scan.radstep = message.radstep;
  scan.max_range = max_range_m;
  scan.ranges = std::move(message.ranges);
  scan.T_body_sensor = T_body_sensor;
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

Decoded<Keyframe> DecodeKeyframe(const void* data, size_t size) {
  anchormap::keyframe_t m;
  if (auto p = SafeDecode(data, size, CheckKeyframeWire, &m)) return FromProblem<Keyframe>(*p);
  if (auto p = CheckName(m.robot, "robot")) return FromProblem<Keyframe>(*p);
  if (m.seq < 0) return Decoded<Keyframe>::Fail(ErrorCode::kBadSequence, "negative seq");
  if (m.utime < 0) return Decoded<Keyframe>::Fail(ErrorCode::kInvalidValue, "negative utime");
  if (!AllFinite(m.pose, 3) || !AllFinite(m.delta, 3) || !AllFinite(m.delta_covariance, 9) ||
      !AllFinite(m.sensor_offset, 3) || !std::isfinite(m.max_range)) {
    return Decoded<Keyframe>::Fail(ErrorCode::kNotFinite, "pose, delta, covariance or offset");
  }
  const Eigen::Matrix3d covariance = MatrixFromRowMajor(m.delta_covariance);
  if (auto why = CheckSymmetricPositiveDefinite(covariance)) {
    return Decoded<Keyframe>::Fail(ErrorCode::kCovarianceNotSpd, "delta_covariance: " + *why);
  }
  if (!(m.max_range > 0.0f))
    return Decoded<Keyframe>::Fail(ErrorCode::kInvalidValue, "max_range <= 0");
  if (auto p = CheckScanGeometry(m.rad0, m.radstep, m.ranges.size()))
    return FromProblem<Keyframe>(*p);
  if (auto p = CheckRanges(m.ranges)) return FromProblem<Keyframe>(*p);

  Keyframe k;
  k.robot = m.robot;
  k.trajectory_id = m.trajectory_id;
  k.seq = m.seq;
  k.utime = m.utime;
  k.T_local_pose = PoseFromArray(m.pose);
  k.T_previous_pose = PoseFromArray(m.delta);
  k.delta_covariance = covariance;
  k.scan.utime = m.utime;
  k.scan.rad0 = m.rad0;
  k.scan.radstep = m.radstep;
  k.scan.max_range = m.max_range;
  k.scan.ranges = std::move(m.ranges);
  k.scan.T_body_sensor = PoseFromArray(m.sensor_offset);
  return Success(std::move(k));
}

std::vector<uint8_t> EncodeKeyframe(const Keyframe& k) {
  anchormap::keyframe_t m;
  m.utime = k.utime;
  m.robot = k.robot;
  m.trajectory_id = k.trajectory_id;
  m.seq = k.seq;
  PoseToArray(k.T_local_pose, m.pose);
  PoseToArray(k.T_previous_pose, m.delta);
  MatrixToRowMajor(k.delta_covariance, m.delta_covariance);
  PoseToArray(k.scan.T_body_sensor, m.sensor_offset);
  m.rad0 = k.scan.rad0;
  m.radstep = k.scan.radstep;
  m.max_range = k.scan.max_range;
  m.nranges = static_cast<int32_t>(k.scan.ranges.size());
  m.ranges = k.scan.ranges;
  return Encode(m);
}

Decoded<Encounter> DecodeEncounter(const void* data, size_t size) {
  anchormap::encounter_t m;
  if (auto p = SafeDecode(data, size, CheckEncounterWire, &m)) return FromProblem<Encounter>(*p);
  if (auto p = CheckName(m.observer, "observer")) return FromProblem<Encounter>(*p);
  if (auto p = CheckName(m.observed, "observed")) return FromProblem<Encounter>(*p);
  if (m.observer == m.observed) {
    return Decoded<Encounter>::Fail(ErrorCode::kSelfEncounter, m.observer + " observed itself");
  }
  if (m.utime < 0) return Decoded<Encounter>::Fail(ErrorCode::kInvalidValue, "negative utime");
  if (!AllFinite(m.relative_pose, 3) || !AllFinite(m.covariance, 9)) {
    return Decoded<Encounter>::Fail(ErrorCode::kNotFinite, "relative pose or covariance");
  }
  const Eigen::Matrix3d covariance = MatrixFromRowMajor(m.covariance);
  if (auto why = CheckSymmetricPositiveDefinite(covariance)) {
    return Decoded<Encounter>::Fail(ErrorCode::kCovarianceNotSpd, "covariance: " + *why);
  }
  Encounter e;
  e.utime = m.utime;
  e.observer = m.observer;
  e.observer_trajectory_id = m.observer_trajectory_id;
  e.observed = m.observed;
  e.T_observer_observed = PoseFromArray(m.relative_pose);
  e.covariance = covariance;
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
  return Encode(m);
}

}  // namespace anchormap
