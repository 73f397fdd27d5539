#pragma once
// Colours of the rendered maps and plots: one distinct colour per trajectory, the same in
// the map and in the anchor-uncertainty plot.

#include <cstdint>
#include <string>
#include <vector>

namespace anchormap::render {

struct Rgb {
  uint8_t r = 0;
  uint8_t g = 0;
  uint8_t b = 0;
  bool operator==(const Rgb& other) const { return r == other.r && g == other.g && b == other.b; }
};

// Colour number `index`: ten well-separated colours first (Tableau 10 without its grey,
// which the occupancy grid uses), then golden-angle hues for larger teams.
Rgb TrajectoryColor(int index);

// A trajectory's identity in the server's output.
struct TrajectoryKey {
  std::string robot;
  int64_t trajectory_id = 0;
  bool operator<(const TrajectoryKey& other) const;  // natural robot order (R2 < R10), then id
  bool operator==(const TrajectoryKey& other) const {
    return robot == other.robot && trajectory_id == other.trajectory_id;
  }
};

// Colour index per trajectory: the position of its key among all keys, in natural order.
class ColorAssignment {
 public:
  explicit ColorAssignment(std::vector<TrajectoryKey> keys);
  Rgb ColorOf(const TrajectoryKey& key) const;

 private:
  std::vector<TrajectoryKey> keys_;  // sorted, unique
};

}  // namespace anchormap::render
