#pragma once
// Variable keys of the multi-robot pose graph: robot poses, keyed by trajectory and
// index, and one anchor per trajectory (docs/METHOD.md section 4).

#include <cstdint>
#include <functional>
#include <string>

namespace anchormap {

// One robot trajectory (one session of one robot). Any non-negative value.
using TrajectoryId = int64_t;

struct PoseKey {
  TrajectoryId trajectory = 0;
  int32_t index = 0;  // keyframe index within the trajectory, 0, 1, 2, ...
  bool operator==(const PoseKey& o) const { return trajectory == o.trajectory && index == o.index; }
};

struct AnchorKey {
  TrajectoryId trajectory = 0;
  bool operator==(const AnchorKey& o) const { return trajectory == o.trajectory; }
};

// Either kind of variable, for covariance queries and orderings.
struct Key {
  Key() = default;
  Key(PoseKey pose) : trajectory(pose.trajectory), index(pose.index) {}          // NOLINT
  Key(AnchorKey anchor) : trajectory(anchor.trajectory), index(kAnchorIndex) {}  // NOLINT

  bool is_anchor() const { return index == kAnchorIndex; }
  PoseKey pose() const { return {trajectory, index}; }
  bool operator==(const Key& o) const { return trajectory == o.trajectory && index == o.index; }
  std::string ToString() const;

  static constexpr int32_t kAnchorIndex = -1;
  TrajectoryId trajectory = 0;
  int32_t index = 0;
};

struct KeyHash {
  size_t operator()(const Key& k) const {
    return std::hash<uint64_t>()(static_cast<uint64_t>(k.trajectory) * 0x9E3779B97F4A7C15ULL ^
                                 static_cast<uint32_t>(k.index));
  }
};

}  // namespace anchormap
