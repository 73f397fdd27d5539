#include "tools/eval/odometry_completion.h"

#include <algorithm>

namespace anchormap {
namespace {

auto ByTime() {
  return [](const StampedPose2& pose, int64_t t) { return pose.utime < t; };
}

}  // namespace

std::optional<Pose2> InterpolateOdometry(const StampedTrajectory& odometry, int64_t utime,
                                         int64_t max_sample_gap_us) {
  const auto after = std::lower_bound(odometry.begin(), odometry.end(), utime, ByTime());
  if (after == odometry.end()) return std::nullopt;
  if (after->utime == utime) return after->pose;
  if (after == odometry.begin()) return std::nullopt;
  const StampedPose2& a = *(after - 1);
  const StampedPose2& b = *after;
  if (b.utime - a.utime > max_sample_gap_us) return std::nullopt;
  const double s = static_cast<double>(utime - a.utime) / static_cast<double>(b.utime - a.utime);
  return Interpolate(a.pose, b.pose, s);
}

StampedTrajectory CompleteWithOdometry(const StampedTrajectory& keyframes,
                                       const StampedTrajectory& odometry,
                                       const std::vector<int64_t>& query_utimes,
                                       int64_t max_extrapolation_us, int64_t max_sample_gap_us) {
  StampedTrajectory completed;
  if (keyframes.empty()) return completed;
  for (int64_t t : query_utimes) {
    if (t < keyframes.front().utime - max_extrapolation_us ||
        t > keyframes.back().utime + max_extrapolation_us) {
      continue;
    }
    const auto after = std::lower_bound(keyframes.begin(), keyframes.end(), t, ByTime());
    const StampedPose2* nearest = after == keyframes.end() ? &keyframes.back() : &*after;
    if (after != keyframes.begin() &&
        (after == keyframes.end() || t - (after - 1)->utime <= after->utime - t)) {
      nearest = &*(after - 1);
    }
    const auto odom_at_keyframe = InterpolateOdometry(odometry, nearest->utime, max_sample_gap_us);
    const auto odom_at_t = InterpolateOdometry(odometry, t, max_sample_gap_us);
    if (!odom_at_keyframe || !odom_at_t) continue;
    completed.push_back({t, Compose(nearest->pose, Between(*odom_at_keyframe, *odom_at_t))});
  }
  std::sort(completed.begin(), completed.end(),
            [](const StampedPose2& a, const StampedPose2& b) { return a.utime < b.utime; });
  completed.erase(
      std::unique(completed.begin(), completed.end(),
                  [](const StampedPose2& a, const StampedPose2& b) { return a.utime == b.utime; }),
      completed.end());
  return completed;
}

}  // namespace anchormap
