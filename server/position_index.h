#pragma once
// Which of a trajectory's keyframes (or submap centres) lie near a point of its frame,
// without looking at all of them: their positions bucketed in a grid hash (cell_m
// squares). The scan-matching sources ask this for every new keyframe (loop candidates
// within a few metres; the nearest submap of a teammate); scanning every keyframe cost
// O(map) per keyframe, so a 30-minute run slowed down as its map grew.
//
// The positions are estimates, which move. The caller refreshes them (Rebuild) when they
// may have moved much (a data-time period, a group merge) and asks with a radius widened by
// the motion it allows between refreshes; it then measures the exact distances itself.

#include <cstdint>
#include <unordered_map>
#include <utility>
#include <vector>

#include <Eigen/Core>

namespace anchormap {

class PositionIndex {
 public:
  explicit PositionIndex(double cell_m) : cell_m_(cell_m) {}

  void Clear();
  void Add(int32_t item, const Eigen::Vector2d& position);
  // The items whose stored position is within `radius` of `center`, in increasing order.
  std::vector<int32_t> Near(const Eigen::Vector2d& center, double radius) const;
  size_t size() const { return size_; }
  // Every stored (item, position), by cell then in the order added (snapshots: Add them
  // again to rebuild an index that answers Near the same).
  std::vector<std::pair<int32_t, Eigen::Vector2d>> Entries() const;

 private:
  struct Entry {
    int32_t item;
    Eigen::Vector2d position;
  };
  int64_t Cell(double coordinate) const;
  static uint64_t CellKey(int64_t cx, int64_t cy);

  double cell_m_;
  std::unordered_map<uint64_t, std::vector<Entry>> cells_;
  size_t size_ = 0;
};

}  // namespace anchormap
