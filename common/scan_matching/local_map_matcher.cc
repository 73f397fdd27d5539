#include "common/scan_matching/local_map_matcher.h"

#include <cmath>
#include <stdexcept>
#include <vector>

namespace anchormap {

Status LocalMapMatcherOptions::Validate() const {
  if (max_keyframes < 1 || max_keyframes > 1000)
    return Status::Error("max_keyframes must be in [1, 1000]");
  if (!(keyframe_distance_m >= 0.0) || !(keyframe_angle_rad >= 0.0)) {
    return Status::Error("keyframe_distance_m and keyframe_angle_rad must be >= 0");
  }
  if (!(max_range_m > 0.0) || !std::isfinite(max_range_m))
    return Status::Error("max_range_m must be > 0");
  if (!(min_overlap >= 0.0 && min_overlap <= 1.0))
    return Status::Error("min_overlap must be in [0, 1]");
  if (!(min_score >= 0.0 && min_score <= 1.0)) return Status::Error("min_score must be in [0, 1]");
  if (!(held_back_min_odometry_m > 0.0))
    return Status::Error("held_back_min_odometry_m must be > 0");
  if (Status valid = reference.Validate(); !valid.ok()) return valid;
  if (Status valid = flat_direction.Validate(); !valid.ok()) return valid;
  // The flat test shifts by the reach the window could have slid, and the covariance gets
  // that reach along the axis: a different window with the old reach would claim too little
  // or too much.
  if (flat_direction.reach_m != match.linear_window_m) {
    return Status::Error("flat_direction.reach_m must equal match.linear_window_m");
  }
  return match.Validate();
}

LocalMapMatcher::LocalMapMatcher(const LocalMapMatcherOptions& options) : options_(options) {
  if (const Status valid = options.Validate(); !valid.ok()) {
    throw std::invalid_argument("LocalMapMatcher: " + valid.message());
  }
}

void LocalMapMatcher::AddKeyframe(const PointCloud& points, const Pose2& pose,
                                  const Pose2& odometry) {
  keyframes_.push_back(
      {pose, odometry,
       std::make_shared<const ScanSurface>(
           MakeScanSurface(TransformPointCloud(points, pose), options_.reference.max_join_gap_m))});
  while (static_cast<int>(keyframes_.size()) > options_.max_keyframes) keyframes_.pop_front();
  std::vector<std::shared_ptr<const ScanSurface>> surfaces;
  surfaces.reserve(keyframes_.size());
  for (const Keyframe& k : keyframes_) surfaces.push_back(k.surface);
  reference_ = std::make_unique<ScanReference>(surfaces, options_.reference);
  ++stats_.keyframes;
}

bool LocalMapMatcher::HeldBack(const Pose2& matched, const Pose2& T_odom_body) const {
  const Keyframe& newest = keyframes_.back();
  const double by_odometry_m = Between(newest.odometry, T_odom_body).translation().norm();
  const double by_match_m = Between(newest.pose, matched).translation().norm();
  return by_odometry_m >= options_.held_back_min_odometry_m && by_match_m < 0.5 * by_odometry_m;
}

LocalMapUpdate LocalMapMatcher::AddScan(const PointCloud& points, const Pose2& T_odom_body,
                                        const std::function<bool(const Pose2&)>& needs_covariance) {
  ++stats_.scans;
  PointCloud near;
  near.reserve(points.size());
  const double max_sq = options_.max_range_m * options_.max_range_m;
  for (const Eigen::Vector2d& p : points) {
    if (p.squaredNorm() <= max_sq) near.push_back(p);
  }
  LocalMapUpdate update;
  update.predicted =
      last_odometry_ ? Compose(last_pose_, Between(*last_odometry_, T_odom_body)) : T_odom_body;
  update.pose = update.predicted;
  last_odometry_ = T_odom_body;
  if (reference_ == nullptr) {
    last_pose_ = update.pose;
    if (!near.empty()) {
      AddKeyframe(near, update.pose, T_odom_body);
      update.keyframe = true;
    }
    return update;
  }
  LocalMatchOptions search = options_.match;
  if (needs_covariance) search.match.covariance = false;
  update.match = MatchLocal(*reference_, near, update.predicted, search);
  bool has_covariance = search.match.covariance;
  if (!update.match) {
    ++stats_.no_match;
  } else if (update.match->score >= options_.min_score &&
             update.match->overlap >= options_.min_overlap) {
    update.matched = true;
    update.pose = update.match->pose;
    ++stats_.matched;
    if (options_.follow_odometry_along_flat_direction) {
      update.flat =
          FindFlatDirection(*reference_, near, update.match->pose, options_.flat_direction);
    }
    if (update.flat) {
      // Where on the ridge the optimum fell is noise (often the window's edge): odometry from
      // the last scan knows the position along it better.
      const Eigen::Vector2d& axis = update.flat->axis;
      const Eigen::Vector2d t =
          update.pose.translation() +
          axis * axis.dot(update.predicted.translation() - update.pose.translation());
      update.pose = Pose2(t.x(), t.y(), update.pose.theta());
      ++stats_.flat;
    }
  } else {
    ++stats_.rejected;
  }
  bool held_back = false;
  if (update.matched && HeldBack(update.pose, T_odom_body)) {
    // Odometry from the map's newest scan, not from the last (possibly held back) pose.
    const Keyframe& newest = keyframes_.back();
    update.matched = false;
    update.pose = Compose(newest.pose, Between(newest.odometry, T_odom_body));
    --stats_.matched;
    ++stats_.held_back;
    held_back = true;
    if (update.flat) --stats_.flat;
    update.flat.reset();
  }
  last_pose_ = update.pose;
  const Pose2 since = Between(keyframes_.back().pose, update.pose);
  const bool moved = since.translation().norm() >= options_.keyframe_distance_m ||
                     std::abs(since.theta()) >= options_.keyframe_angle_rad;
  const bool lost = since.translation().norm() >= 3.0 * options_.keyframe_distance_m ||
                    std::abs(since.theta()) >= 3.0 * options_.keyframe_angle_rad;
  if (update.matched && search.match.covariance != options_.match.match.covariance &&
      (moved || needs_covariance(update.pose))) {
    // Against the reference the pose was found in, before a new keyframe changes it.
    AddCovariance(*reference_, near, options_.match.match, &*update.match);
    has_covariance = true;
  }
  if (update.matched && update.flat && has_covariance) {
    // The match claims the refinement's millimetres along the ridge (far lone returns fit
    // point to point); the score says the window's reach.
    const Eigen::Vector2d& axis = update.flat->axis;
    const double reach = options_.flat_direction.reach_m;
    update.match->covariance.topLeftCorner<2, 2>() += reach * reach * axis * axis.transpose();
  }
  if (update.matched && moved) {
    AddKeyframe(near, update.pose, T_odom_body);
    update.keyframe = true;
  } else if (!update.matched && (lost || held_back) && !near.empty()) {
    // The map no longer matches where odometry took us: start a new one here rather than
    // keep matching against a stale map or adding unverified poses to it.
    keyframes_.clear();
    AddKeyframe(near, update.pose, T_odom_body);
    update.keyframe = true;
    ++stats_.resets;
  }
  return update;
}

}  // namespace anchormap
