#pragma once
// Odometry refinement on the robot (issue 11, item 2), without a bus: each new scan is matched
// against a local map of the last keyframes' points, around the pose odometry predicts; when
// the match is good the scan's pose becomes the matched one, otherwise the prediction, and the
// caller is told which. Poses are in the trajectory's local frame: the first scan's odometry
// pose anchors it, and refined poses drift from odometry as corrections accumulate.
//
// Memory is bounded: at most max_keyframes scans' points (each cut at max_range_m) and one
// ScanReference over them (the grid spans their extent, at most 2 (max_range_m + margin) per
// side around the keyframes). The reference is rebuilt when a keyframe enters the map.

#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/scan_matching/correlative_matcher.h"
#include "common/scan_matching/flat_direction.h"
#include "common/scan_matching/point_cloud.h"
#include "common/scan_matching/scan_reference.h"
#include "common/util/status.h"

namespace anchormap {

struct LocalMapMatcherOptions {
  int max_keyframes = 10;            // scans in the local map
  double keyframe_distance_m = 0.3;  // a scan enters the map this far from the last one
  double keyframe_angle_rad = 0.26;  // or turned this much (15 degrees)
  double max_range_m = 15.0;         // points farther from the robot are not used
  double min_overlap = 0.6;          // a good match: overlap at least this ...
  double min_score = 0.45;           // ... and a lattice score at least this
  // A good match is refused as held back when odometry drove at least this far since the
  // map's newest scan while the match moved the robot less than half as far: along a corridor
  // the match can hold the robot back while it drives on (ACES: 4.7 m of odometry in 8 s
  // matched as 0.7 m). A true snap back onto the map corrects about one keyframe spacing once,
  // and the next keyframe follows. The pose then follows odometry and the map restarts there.
  double held_back_min_odometry_m = 1.0;
  ScanReferenceOptions reference{0.05, 0.05, 0.5, 4};  // 4 levels: blocks of 8 cells
  LocalMatchOptions match;                             // the window around the prediction
  // Along a direction where a good match's score stays flat over the window's reach (a
  // featureless corridor: FindFlatDirection), the match does not know where the robot is: the
  // pose keeps the prediction's (odometry's) position along it, and the covariance gets the
  // reach's spread along it. Off (`follow_odometry_along_flat_direction` false): the match's.
  bool follow_odometry_along_flat_direction = true;
  FlatDirectionOptions flat_direction;  // reach_m: the search window's half-width

  Status Validate() const;
};

struct LocalMapUpdate {
  Pose2 pose;  // T_local_body of the scan: matched when `matched`, else predicted
  Pose2 predicted;
  bool matched = false;
  bool keyframe = false;             // the scan entered the local map
  std::optional<MatchResult> match;  // the match, also when rejected
  // A matched pose along whose `axis` the match's score was flat: `pose` kept the prediction's
  // position along it, and the match's covariance has the reach's spread along it added.
  std::optional<FlatDirection> flat;
};

struct LocalMapStats {
  int64_t scans = 0;
  int64_t matched = 0;
  int64_t rejected = 0;  // a match was found but was not good (score or overlap)
  int64_t no_match = 0;  // nothing above the matcher's min_score, or an empty scan
  int64_t keyframes = 0;
  int64_t resets = 0;     // unmatched scans far from the map restarted it
  int64_t held_back = 0;  // good matches refused as held back (each also restarts the map)
  int64_t flat = 0;       // good matches that followed odometry along a flat direction
};

class LocalMapMatcher {
 public:
  // Options must be valid.
  explicit LocalMapMatcher(const LocalMapMatcherOptions& options);

  // A scan's points in its body frame (ScanToPointCloud) and the body's odometry pose at the
  // scan's time. The prediction is the last scan's pose moved by the odometry since then.
  // With `needs_covariance`, a good match's covariance is computed only when the scan enters
  // the map or the predicate says so for the matched pose (otherwise it stays the identity):
  // the covariance is most of a match's cost. Poses are the same either way.
  LocalMapUpdate AddScan(const PointCloud& points, const Pose2& T_odom_body,
                         const std::function<bool(const Pose2&)>& needs_covariance = nullptr);

  const LocalMapStats& stats() const { return stats_; }
  size_t num_keyframes() const { return keyframes_.size(); }

 private:
  struct Keyframe {
    Pose2 pose;      // T_local_body
    Pose2 odometry;  // T_odom_body at the scan's time
    // The points in the local frame, joined into walls with their normals once: the map's
    // reference is rebuilt from them at every keyframe.
    std::shared_ptr<const ScanSurface> surface;
  };
  void AddKeyframe(const PointCloud& points, const Pose2& pose, const Pose2& odometry);
  bool HeldBack(const Pose2& matched, const Pose2& T_odom_body) const;

  LocalMapMatcherOptions options_;
  std::deque<Keyframe> keyframes_;
  std::unique_ptr<ScanReference> reference_;
  std::optional<Pose2> last_odometry_;
  Pose2 last_pose_;
  LocalMapStats stats_;
};

}  // namespace anchormap
