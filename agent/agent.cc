#include "agent/agent.h"

#include <algorithm>
#include <cmath>

namespace anchormap {

Eigen::Matrix3d OdometryDeltaCovariance(const OdometryNoiseOptions& noise,
                                        const Pose2& T_previous_pose) {
  const double distance = T_previous_pose.translation().norm();
  const double angle = std::abs(T_previous_pose.theta());
  const double sigma_xy = noise.xy_base_m + noise.xy_per_m * distance;
  const double sigma_theta =
      noise.theta_base_rad + noise.theta_per_rad * angle + noise.theta_per_m * distance;
  return Eigen::Vector3d(sigma_xy * sigma_xy, sigma_xy * sigma_xy, sigma_theta * sigma_theta)
      .asDiagonal();
}

Agent::Agent(const AgentOptions& options)
    : options_(options),
      T_body_sensor_(options.sensor_x_m, options.sensor_y_m, options.sensor_theta_rad),
      odometry_(options.odometry),
      keyframer_(options.keyframer) {}

std::optional<ErrorCode> Agent::OnOdometry(const OdometrySample& sample, AgentOutput* out) {
  if (auto reason = odometry_.Add(sample)) return reason;
  ++stats_.odometry_readings;
  DrainPendingScans(out);
  return std::nullopt;
}

std::optional<ErrorCode> Agent::OnScan(const LaserScan& scan, AgentOutput* out) {
  const int64_t newest_seen =
      pending_scans_.empty() ? last_scan_utime_ : pending_scans_.back().utime;
  if (scan.utime <= newest_seen) return ErrorCode::kOutOfOrder;
  ++stats_.scans;
  LaserScan copy = scan;
  copy.T_body_sensor = T_body_sensor_;
  copy.max_range = static_cast<float>(options_.max_range_m);
  if (odometry_.empty() || scan.utime > odometry_.newest_utime()) {
    // Odometry has not reached this scan's time yet: wait for it (bounded).
    pending_scans_.push_back(std::move(copy));
    if (pending_scans_.size() > static_cast<size_t>(options_.max_pending_scans)) {
      pending_scans_.pop_front();
      out->late_rejections.push_back(ErrorCode::kQueueFull);
    }
    return std::nullopt;
  }
  if (!pending_scans_.empty()) DrainPendingScans(out);
  const auto pose = odometry_.PoseAt(scan.utime);
  if (!pose) {
    last_scan_utime_ = scan.utime;
    return ErrorCode::kNoOdometry;
  }
  ProcessScan(copy, *pose, out);
  return std::nullopt;
}

void Agent::DrainPendingScans(AgentOutput* out) {
  while (!pending_scans_.empty() && pending_scans_.front().utime <= odometry_.newest_utime()) {
    const LaserScan scan = std::move(pending_scans_.front());
    pending_scans_.pop_front();
    const auto pose = odometry_.PoseAt(scan.utime);
    if (!pose) {
      last_scan_utime_ = scan.utime;
      out->late_rejections.push_back(ErrorCode::kNoOdometry);
      continue;
    }
    ProcessScan(scan, *pose, out);
  }
}

void Agent::ProcessScan(const LaserScan& scan, const Pose2& T_odom_body, AgentOutput* out) {
  last_scan_utime_ = scan.utime;
  if (!keyframer_.ShouldMake(T_odom_body, scan.utime)) return;
  if (keyframer_.IsForcedAt(scan.utime)) ++stats_.forced_keyframes;
  keyframer_.Accept(T_odom_body, scan.utime);

  Keyframe keyframe;
  keyframe.robot = options_.robot;
  keyframe.trajectory_id = options_.trajectory_id;
  keyframe.seq = next_seq_++;
  keyframe.utime = scan.utime;
  // The odometry frame is the trajectory's local frame.
  keyframe.T_local_pose = T_odom_body;
  if (last_keyframe_pose_) {
    keyframe.T_previous_pose = Between(*last_keyframe_pose_, T_odom_body);
    keyframe.delta_covariance = OdometryDeltaCovariance(options_.noise, keyframe.T_previous_pose);
  }
  keyframe.scan = scan;
  last_keyframe_pose_ = T_odom_body;
  ++stats_.keyframes;
  out->keyframes.push_back(std::move(keyframe));
}

std::optional<ErrorCode> Agent::OnEncounter(const Encounter& encounter, AgentOutput* out) {
  if (encounter.observer != options_.robot) return ErrorCode::kWrongRobot;
  if (encounter.observed == options_.robot) return ErrorCode::kSelfEncounter;
  Encounter relayed = encounter;
  relayed.observer_trajectory_id = options_.trajectory_id;
  // Keyframe at the first scan at or after the encounter (or the next scan if the
  // encounter arrives late), so the server finds one close in time.
  keyframer_.ForceAtOrAfter(std::max(encounter.utime, last_scan_utime_ + 1));
  ++stats_.encounters_relayed;
  out->encounters.push_back(std::move(relayed));
  return std::nullopt;
}

void Agent::OnRelayedEncounter(const Encounter& encounter) {
  if (encounter.observed != options_.robot) return;
  keyframer_.ForceAtOrAfter(std::max(encounter.utime, last_scan_utime_ + 1));
}

}  // namespace anchormap
