#include "agent/agent.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

namespace anchormap {

Agent::Agent(const AgentOptions& options)
    : options_(options),
      T_body_sensor_(options.sensor_x_m, options.sensor_y_m, options.sensor_theta_rad),
      odometry_(options.odometry),
      keyframer_(options.keyframer),
      refiner_(options.scan_matching) {}

Status Agent::OnOdometry(const OdometrySample& sample, AgentOutput* out) {
  if (Status added = odometry_.Add(sample); !added.ok()) return added;
  ++stats_.odometry_readings;
  DrainPendingScans(out);
  return Status::Ok();
}

Status Agent::OnScan(LaserScan scan, AgentOutput* out) {
  const int64_t newest_seen =
      pending_scans_.empty() ? last_scan_utime_ : pending_scans_.back().utime;
  if (scan.utime <= newest_seen) {
    return Status::Error(
        ErrorCode::kOutOfOrder,
        "scan at " + std::to_string(scan.utime) + " is not after " + std::to_string(newest_seen));
  }
  ++stats_.scans;
  // The one place where the robot's mounting pose and range limit join the scan.
  scan.T_body_sensor = T_body_sensor_;
  scan.max_range = static_cast<float>(options_.max_range_m);
  if (odometry_.empty() || scan.utime > odometry_.newest_utime()) {
    // Odometry has not reached this scan's time yet: wait for it (bounded).
    pending_scans_.push_back(std::move(scan));
    if (pending_scans_.size() > static_cast<size_t>(options_.max_pending_scans)) {
      out->late_rejections.push_back(Status::Error(
          ErrorCode::kQueueFull, "scan at " + std::to_string(pending_scans_.front().utime) +
                                     " waited for odometry in a full queue"));
      pending_scans_.pop_front();
    }
    return Status::Ok();
  }
  if (!pending_scans_.empty()) DrainPendingScans(out);
  const auto pose = odometry_.PoseAt(scan.utime);
  if (!pose) {
    last_scan_utime_ = scan.utime;
    return Status::Error(ErrorCode::kNoOdometry,
                         "no odometry around the scan at " + std::to_string(scan.utime));
  }
  ProcessScan(std::move(scan), *pose, out);
  return Status::Ok();
}

void Agent::DrainPendingScans(AgentOutput* out) {
  while (!pending_scans_.empty() && pending_scans_.front().utime <= odometry_.newest_utime()) {
    LaserScan scan = std::move(pending_scans_.front());
    pending_scans_.pop_front();
    const auto pose = odometry_.PoseAt(scan.utime);
    if (!pose) {
      last_scan_utime_ = scan.utime;
      out->late_rejections.push_back(
          Status::Error(ErrorCode::kNoOdometry,
                        "no odometry around the waiting scan at " + std::to_string(scan.utime)));
      continue;
    }
    ProcessScan(std::move(scan), *pose, out);
  }
}

void Agent::ProcessScan(LaserScan scan, const Pose2& T_odom_body, AgentOutput* out) {
  last_scan_utime_ = scan.utime;
  // Every scan is matched (not only keyframes): the local map follows the robot closely and
  // the prediction from the last scan is short.
  const int64_t utime = scan.utime;
  const RefinedPose refined = refiner_.Refine(scan, T_odom_body, [this, utime](const Pose2& pose) {
    return keyframer_.ShouldMake(pose, utime);
  });
  if (!keyframer_.ShouldMake(refined.pose, scan.utime)) {
    if (refined.entered_map && refined.matched) {
      map_growth_covariance_ += refined.covariance;
      map_growth_flat_ = map_growth_flat_ || refined.flat;
    }
    return;
  }
  if (keyframer_.IsForcedAt(scan.utime)) ++stats_.forced_keyframes;
  keyframer_.Accept(refined.pose, scan.utime);

  Keyframe keyframe;
  keyframe.robot = options_.robot;
  keyframe.trajectory_id = options_.trajectory_id;
  keyframe.seq = next_seq_++;
  // Every encounter relayed so far went out before this keyframe: the server, seeing this
  // count, knows which it misses even when no later encounter reveals the loss.
  keyframe.encounters_relayed = next_encounter_seq_;
  keyframe.utime = scan.utime;
  // The local frame: the odometry frame, moved by the corrections scan matching made.
  keyframe.T_local_pose = refined.pose;
  if (last_keyframe_) {
    keyframe.T_previous_this = Between(last_keyframe_->pose, refined.pose);
    keyframe.T_previous_this_covariance =
        ConstraintCovariance(*last_keyframe_, refined, keyframe.T_previous_this);
  }
  keyframe.scan = std::move(scan);
  last_keyframe_ = refined;
  map_growth_covariance_.setZero();
  map_growth_flat_ = false;
  ++stats_.keyframes;
  out->keyframes.push_back(std::move(keyframe));
}

Eigen::Matrix3d Agent::ConstraintCovariance(const RefinedPose& previous, const RefinedPose& current,
                                            const Pose2& T_previous_this) {
  if (previous.in_map && current.in_map && previous.map_generation == current.map_generation) {
    ++stats_.matched_constraints;
    // Both matched against the map, which meanwhile grew by scans with errors of their own:
    // those add to the current pose's error relative to the previous one.
    const Eigen::Matrix3d matched =
        RelativePoseCovariance(previous.pose, previous.covariance, current.pose,
                               current.covariance + map_growth_covariance_);
    if (!(previous.flat || current.flat || map_growth_flat_)) return matched;
    // Along a flat direction the poses followed odometry, and the matches' covariances say
    // they know nothing there: the constraint is the matches' and the wheels' information.
    ++stats_.flat_constraints;
    const Eigen::Matrix3d fused =
        (matched.inverse() + options_.noise.Covariance(T_previous_this).inverse()).inverse();
    return 0.5 * (fused + fused.transpose());
  }
  ++stats_.odometry_constraints;
  return options_.noise.Covariance(T_previous_this);
}

Status Agent::SetSensorMounting(const Pose2& T_body_sensor) {
  if (!std::isfinite(T_body_sensor.x()) || !std::isfinite(T_body_sensor.y()) ||
      !std::isfinite(T_body_sensor.theta())) {
    return Status::Error(ErrorCode::kNotFinite, "laser mounting pose is not finite");
  }
  T_body_sensor_ = T_body_sensor;
  return Status::Ok();
}

Status Agent::OnEncounter(const Encounter& encounter, AgentOutput* out) {
  if (encounter.observer != options_.robot) {
    return Status::Error(ErrorCode::kWrongRobot,
                         "observer " + encounter.observer + " is not " + options_.robot);
  }
  if (encounter.observed == options_.robot) {
    return Status::Error(ErrorCode::kSelfEncounter, encounter.observer + " observed itself");
  }
  Encounter relayed = encounter;
  relayed.observer_trajectory_id = options_.trajectory_id;
  relayed.seq = next_encounter_seq_++;
  // Keyframe at the first scan at or after the encounter (or the next scan if the
  // encounter arrives late), so the server finds one close in time.
  keyframer_.ForceAtOrAfter(std::max(encounter.utime, last_scan_utime_ + 1));
  ++stats_.encounters_relayed;
  out->encounters.push_back(std::move(relayed));
  return Status::Ok();
}

void Agent::OnRelayedEncounter(const Encounter& encounter) {
  if (encounter.observed != options_.robot) return;
  keyframer_.ForceAtOrAfter(std::max(encounter.utime, last_scan_utime_ + 1));
}

}  // namespace anchormap
