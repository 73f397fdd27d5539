#include "server/delivery.h"

namespace anchormap {

bool SeqWindow::Insert(int32_t seq) {
  if (Contains(seq)) return false;
  if (seq == next_) {
    ++next_;
    while (!above_.empty() && *above_.begin() == next_) {
      above_.erase(above_.begin());
      ++next_;
    }
  } else {
    above_.insert(seq);
  }
  return true;
}

std::vector<std::pair<int32_t, int32_t>> SeqWindow::Missing() const {
  std::vector<std::pair<int32_t, int32_t>> ranges;
  int32_t first_unknown = next_;
  for (int32_t seq : above_) {
    if (seq > first_unknown) ranges.emplace_back(first_unknown, seq - 1);
    first_unknown = seq + 1;
  }
  // The tail no later arrival revealed, only a keyframe's count.
  if (expected_ > first_unknown) ranges.emplace_back(first_unknown, expected_ - 1);
  return ranges;
}

int32_t SeqWindow::GiveUpMissing() {
  const int32_t end = std::max(above_.empty() ? next_ : *above_.rbegin() + 1, expected_);
  if (end <= next_) return 0;
  const int32_t given_up = end - next_ - static_cast<int32_t>(above_.size());
  next_ = end;
  above_.clear();
  return given_up;
}

bool ResendTracker::Due(const TrajectoryName& trajectory, int64_t now_utime) {
  const auto it = last_request_utime_.find(trajectory);
  if (it != last_request_utime_.end() &&
      1e-6 * static_cast<double>(now_utime - it->second) < options_.resend_period_s) {
    return false;
  }
  last_request_utime_[trajectory] = now_utime;
  return true;
}

}  // namespace anchormap
