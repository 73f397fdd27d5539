#pragma once
// The worker threads of the server's scan-matching sources (issue 11, item 6). A source
// hands the pool a job that reads only what the job owns (a point cloud, a shared immutable
// ScanReference, a predicted pose) and gets a future; it uses the result at a fixed point
// of the canonical input (MatchSchedule), waiting for it if the job is not done, so that
// what the server accepts never depends on thread timing or on the number of workers.
// With 0 workers a job runs at once on the caller's thread (the same results).

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <future>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include "common/scan_matching/correlative_matcher.h"

namespace anchormap {

// When a source uses a match: once the canonical input has reached the query keyframe's
// time plus lag_s (data time), i.e. at the source's first Poll at or after it.
struct MatchSchedule {
  double lag_s = 0.0;
  int64_t DueUtime(int64_t keyframe_utime) const {
    return keyframe_utime + static_cast<int64_t>(1e6 * lag_s);
  }
};

class MatchPool {
 public:
  using Job = std::function<std::optional<MatchResult>()>;

  explicit MatchPool(int workers);
  ~MatchPool();
  MatchPool(const MatchPool&) = delete;
  MatchPool& operator=(const MatchPool&) = delete;

  std::shared_future<std::optional<MatchResult>> Submit(Job job);
  int workers() const { return static_cast<int>(threads_.size()); }

 private:
  void Work();

  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::packaged_task<std::optional<MatchResult>()>> queue_;
  bool stopping_ = false;
  std::vector<std::thread> threads_;
};

// Runs `job` on `pool`, or at once on the caller's thread when there is no pool (the
// sources' 0-worker mode): either way the caller gets a future of its result.
std::shared_future<std::optional<MatchResult>> RunMatch(MatchPool* pool, MatchPool::Job job);

}  // namespace anchormap
