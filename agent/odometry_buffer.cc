#include "agent/odometry_buffer.h"

#include <algorithm>

namespace anchormap {

Status OdometryBuffer::Add(const OdometrySample& sample) {
  if (!samples_.empty() && sample.utime <= samples_.back().utime) {
    return Status::Error(ErrorCode::kOutOfOrder, "odometry at " + std::to_string(sample.utime) +
                                                     " is not after " +
                                                     std::to_string(samples_.back().utime));
  }
  samples_.push_back(sample);
  while (samples_.size() > static_cast<size_t>(options_.capacity)) samples_.pop_front();
  return Status::Ok();
}

std::optional<Pose2> OdometryBuffer::PoseAt(int64_t utime) const {
  if (samples_.empty() || utime < samples_.front().utime || utime > samples_.back().utime) {
    return std::nullopt;
  }
  // The first reading at or after utime.
  const auto after =
      std::lower_bound(samples_.begin(), samples_.end(), utime,
                       [](const OdometrySample& s, int64_t t) { return s.utime < t; });
  if (after->utime == utime) return after->T_odom_body;
  const auto before = std::prev(after);
  const double span_s = 1e-6 * static_cast<double>(after->utime - before->utime);
  if (span_s > options_.max_gap_s) return std::nullopt;
  const double fraction = static_cast<double>(utime - before->utime) /
                          static_cast<double>(after->utime - before->utime);
  return Interpolate(before->T_odom_body, after->T_odom_body, fraction);
}

}  // namespace anchormap
