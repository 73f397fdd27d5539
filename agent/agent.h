#pragma once
// The agent's logic, one per robot, with no bus: odometry readings and laser scans in,
// keyframes out (docs/ARCHITECTURE.md "A keyframe's path", steps 1-2). Each scan gets the odometry
// pose at its own time; the Keyframer picks the scans that become keyframes; each keyframe
// carries its pose in the trajectory's local frame and its constraint to the previous keyframe.
// With scan matching on (the default), every scan is first matched against a local map of the
// last scans (ScanRefiner): a good match gives the pose and, when the previous keyframe is in the
// same local map too, the constraint with the matcher's covariance; otherwise the odometry delta
// with a covariance from the noise model (counted). Direct encounters the robot
// observed are relayed with its trajectory id and a sequence number of their own, and a keyframe is
// forced at the next scan so the server finds one near the encounter's time. Memory is bounded: the
// odometry history, a few scans waiting for odometry, one pose, the local map's few scans.

#include <cstdint>
#include <deque>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "agent/agent_options.h"
#include "agent/keyframer.h"
#include "agent/odometry_buffer.h"
#include "agent/scan_refiner.h"
#include "common/types/encounter.h"
#include "common/types/keyframe.h"
#include "common/types/laser_scan.h"
#include "common/types/odometry.h"
#include "common/util/status.h"

namespace anchormap {

// What one input produced, in order.
struct AgentOutput {
  std::vector<Keyframe> keyframes;
  std::vector<Encounter> encounters;
  // Earlier inputs refused later (a waiting scan the odometry never covered, or pushed
  // out of the full waiting list); the caller counts them like direct refusals.
  std::vector<Status> late_rejections;
};

struct AgentStats {
  int64_t odometry_readings = 0;
  int64_t scans = 0;
  int64_t keyframes = 0;
  int64_t encounters_relayed = 0;
  int64_t forced_keyframes = 0;
  // Keyframe constraints from scan matching, and from odometry (refinement off, no good match,
  // or the previous keyframe not in the same local map).
  int64_t matched_constraints = 0;
  int64_t odometry_constraints = 0;
  // Of the matched ones, those fused with odometry along a flat direction (a corridor).
  int64_t flat_constraints = 0;
};

class Agent {
 public:
  // `options` must be valid (Validate()), with trajectory_id already chosen.
  explicit Agent(const AgentOptions& options);

  // Each returns why the input is refused, if it is (the caller counts it).
  Status OnOdometry(const OdometrySample& sample, AgentOutput* out);
  // Scans must come in increasing time. A scan newer than the newest odometry waits (up
  // to max_pending_scans) until odometry covers its time.
  Status OnScan(LaserScan scan, AgentOutput* out);
  // An encounter this robot observed (its sensor channel): observer must be this robot.
  Status OnEncounter(const Encounter& encounter, AgentOutput* out);
  // The laser's mounting pose on the body, as the robot's log or driver publishes it (replaces
  // the options' sensor_* from the next scan on). Refused when not finite.
  Status SetSensorMounting(const Pose2& T_body_sensor);
  const Pose2& sensor_mounting() const { return T_body_sensor_; }
  // An encounter seen on the server's channel: if this robot is the observed one, a
  // keyframe is forced near its time too.
  void OnRelayedEncounter(const Encounter& encounter);

  const AgentStats& stats() const { return stats_; }
  const ScanRefinementStats& refinement_stats() const { return refiner_.stats(); }
  size_t pending_scans() const { return pending_scans_.size(); }
  int64_t trajectory_id() const { return options_.trajectory_id; }

 private:
  // Refines the scan's pose, then turns the scan into a keyframe when the Keyframer says so.
  void ProcessScan(LaserScan scan, const Pose2& T_odom_body, AgentOutput* out);
  // The constraint's covariance: the matcher's when both keyframes are in one local map.
  Eigen::Matrix3d ConstraintCovariance(const RefinedPose& previous, const RefinedPose& current,
                                       const Pose2& T_previous_this);
  // Processes waiting scans that the odometry now covers; drops those it never will.
  void DrainPendingScans(AgentOutput* out);

  AgentOptions options_;
  Pose2 T_body_sensor_;
  OdometryBuffer odometry_;
  Keyframer keyframer_;
  std::deque<LaserScan> pending_scans_;
  int64_t last_scan_utime_ = -1;
  int32_t next_seq_ = 0;
  int32_t next_encounter_seq_ = 0;  // relayed encounters' own sequence
  ScanRefiner refiner_;
  std::optional<RefinedPose> last_keyframe_;
  // The covariances (local frame) of the scans that entered the local map since the last
  // keyframe: each moved the map the next scans match against, by its own error.
  Eigen::Matrix3d map_growth_covariance_ = Eigen::Matrix3d::Zero();
  bool map_growth_flat_ = false;  // one of them followed odometry along a flat direction
  AgentStats stats_;
};

}  // namespace anchormap
