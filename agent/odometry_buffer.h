#pragma once
// A bounded history of odometry readings, so that a laser scan can be given the robot's
// pose at the scan's own time stamp (interpolated between the two readings around it),
// instead of "the latest odometry", whose lag would smear keyframes at speed.

#include <cstddef>
#include <cstdint>
#include <deque>
#include <optional>
#include <string>

#include "common/geometry/pose2.h"
#include "common/types/odometry.h"
#include "common/util/reject_counter.h"
#include "common/util/status.h"

namespace anchormap {

struct OdometryBufferOptions {
  // Readings kept (oldest dropped first): 1000 is 20 s at 50 Hz, ~40 kB.
  int capacity = 1000;
  // No interpolation across a gap longer than this between two readings (odometry outage).
  double max_gap_s = 1.0;

  Status Validate() const {
    if (capacity < 2) return Status::Error("odometry.capacity must be >= 2");
    if (!(max_gap_s > 0)) return Status::Error("odometry.max_gap_s must be > 0");
    return Status::Ok();
  }
};

class OdometryBuffer {
 public:
  explicit OdometryBuffer(const OdometryBufferOptions& options = {}) : options_(options) {}

  // Appends a reading; readings must come in strictly increasing time, otherwise
  // the reading is dropped and the Status says kOutOfOrder.
  Status Add(const OdometrySample& sample);

  // The body pose at `utime`, interpolated (linear in x, y; shortest way in theta) between
  // the readings just before and just after; exact at a reading's time. nullopt when
  // `utime` is outside [oldest, newest] or falls in a gap longer than max_gap_s.
  std::optional<Pose2> PoseAt(int64_t utime) const;

  bool empty() const { return samples_.empty(); }
  size_t size() const { return samples_.size(); }
  int64_t oldest_utime() const { return samples_.empty() ? 0 : samples_.front().utime; }
  int64_t newest_utime() const { return samples_.empty() ? 0 : samples_.back().utime; }

 private:
  OdometryBufferOptions options_;
  std::deque<OdometrySample> samples_;
};

}  // namespace anchormap
