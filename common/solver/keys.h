#pragma once
// Variable keys of the multi-robot pose graph: robot poses, keyed by trajectory and
// index, and one anchor per trajectory (docs/METHOD.md section 4).

#include <cstdint>
#include <functional>
#include <ostream>
#include <string>

namespace anchormap {

// The solver's name for one trajectory (one session of one robot). A type of its own so it
// cannot be mixed up with the agent's trajectory id on the bus (a random int64 that
// TrajectoryTable maps to this one): construction from a number is explicit.
class TrajectoryId {
 public:
  constexpr TrajectoryId() = default;
  constexpr explicit TrajectoryId(int64_t value) : value_(value) {}
  constexpr int64_t value() const { return value_; }

  friend constexpr bool operator==(TrajectoryId a, TrajectoryId b) { return a.value_ == b.value_; }
  friend constexpr bool operator!=(TrajectoryId a, TrajectoryId b) { return a.value_ != b.value_; }
  friend constexpr bool operator<(TrajectoryId a, TrajectoryId b) { return a.value_ < b.value_; }
  friend std::ostream& operator<<(std::ostream& os, TrajectoryId id) { return os << id.value_; }

 private:
  int64_t value_ = 0;
};

struct PoseKey {
  TrajectoryId trajectory;
  int32_t index = 0;  // keyframe index within the trajectory, 0, 1, 2, ...
  bool operator==(const PoseKey& o) const { return trajectory == o.trajectory && index == o.index; }
};

struct AnchorKey {
  TrajectoryId trajectory;
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
  TrajectoryId trajectory;
  int32_t index = 0;
};

struct KeyHash {
  size_t operator()(const Key& k) const {
    return std::hash<uint64_t>()(static_cast<uint64_t>(k.trajectory.value()) *
                                     0x9E3779B97F4A7C15ULL ^
                                 static_cast<uint32_t>(k.index));
  }
};

}  // namespace anchormap

namespace std {
template <>
struct hash<anchormap::TrajectoryId> {
  size_t operator()(anchormap::TrajectoryId id) const { return hash<int64_t>()(id.value()); }
};
}  // namespace std
