#pragma once
// A matching reference made of one trajectory's neighbouring keyframes: the scans of
// keyframes [center - half_width, center + half_width] placed at their current estimates
// in the frame of the center keyframe. Loop closures and scan encounters match a new
// keyframe against such a submap rather than against one scan: more walls, fewer aliases.

#include <memory>
#include <utility>
#include <vector>

#include "common/scan_matching/point_cloud.h"
#include "common/scan_matching/scan_reference.h"
#include "common/solver/keys.h"
#include "common/solver/smoother.h"
#include "server/trajectory_table.h"

namespace anchormap {

// The points of keyframe `index` of `record` in its body frame, cut at max_range_m.
PointCloud KeyframePoints(const TrajectoryRecord& record, int index, double max_range_m);

// A submap as drawn: where its keyframes were, in the frame of the center keyframe, at the
// estimates of the time. Cheap to keep; the reference (grids and pyramid, the costly part)
// can be built from it later, with the same bits as at drawing time, and only for the
// submaps a search uses (at 100 robots most are never searched).
struct SubmapDrawing {
  PoseKey center;
  std::vector<std::pair<int, Pose2>> T_center_keyframes;  // (keyframe index, pose)
  size_t num_points = 0;                                  // 0: the reference would be empty
};

// The drawing of the submap around `center` (which the smoother must hold); keyframes the
// smoother does not hold yet are left out.
SubmapDrawing DrawKeyframeSubmap(const TrajectoryRecord& record, const Smoother& smoother,
                                 PoseKey center, int half_width, double max_range_m);

// The drawing of a submap chosen by place, not by index: the keyframes of `center`'s
// trajectory up to `last_index` whose estimates lie within `radius_m` of `at` (a position in
// the frame of `center`), nearest first, each kept unless a kept one stands within spacing_m
// and spacing_rad of it (repeated passes add doubled walls, not views), at most
// `max_keyframes`; in index order. A wide loop search's window (up to 12 m across) is wider
// than the path a submap of 21 consecutive keyframes covers (on ACES the keyframes that saw
// the query's place lay just outside the submap, by index, of the likeliest candidate).
struct PlaceSubmapOptions {
  // Keyframes [keep_first, keep_last] are kept first, whatever their place (none when
  // keep_first > keep_last); max_keyframes and the spacing apply to the ones added by place.
  int keep_first = 0;
  int keep_last = -1;
  double radius_m = 0.0;
  int last_index = 0;
  int max_keyframes = 0;
  double spacing_m = 0.0;
  double spacing_rad = 0.0;
};
SubmapDrawing DrawKeyframeSubmapNear(const TrajectoryRecord& record, const Smoother& smoother,
                                     PoseKey center, const Eigen::Vector2d& at,
                                     const PlaceSubmapOptions& options, double max_range_m);

// The reference of a drawing of `record`'s keyframes; nullptr when it holds no point.
std::unique_ptr<ScanReference> BuildKeyframeSubmap(const TrajectoryRecord& record,
                                                   const SubmapDrawing& drawing, double max_range_m,
                                                   const ScanReferenceOptions& options);

// The submap around `center` (which the smoother must hold); keyframes the smoother does
// not hold yet are left out. nullptr when it holds no point.
std::unique_ptr<ScanReference> BuildKeyframeSubmap(const TrajectoryRecord& record,
                                                   const Smoother& smoother, PoseKey center,
                                                   int half_width, double max_range_m,
                                                   const ScanReferenceOptions& options);

}  // namespace anchormap
