#include "server/global_search_queue.h"

#include <cmath>

#include "server/data_time_tokens.h"

namespace anchormap {

Status GlobalSearchBudgetOptions::Validate() const {
  if (!(searches_per_s >= 0) || !std::isfinite(searches_per_s)) {
    return Status::Error("scan.global_searches_per_s must be finite and >= 0");
  }
  if (!(burst >= 1) || !std::isfinite(burst)) {
    return Status::Error("scan.global_burst must be finite and >= 1");
  }
  return Status::Ok();
}

void GlobalSearchQueue::Advance(int64_t now_utime) {
  RefillTokens(now_utime, options_.searches_per_s, options_.burst, &tokens_, &last_utime_);
}

void GlobalSearchQueue::Enqueue(PoseKey key) {
  const auto [it, inserted] = waiting_.emplace(key.trajectory, key);
  if (!inserted && !(it->second == key)) {
    it->second = key;
    ++dropped_;
  }
}

std::optional<PoseKey> GlobalSearchQueue::Next() const {
  std::optional<PoseKey> next;
  int64_t fewest = 0;
  for (const auto& [trajectory, key] : waiting_) {
    const int64_t count = Searched(trajectory);
    // Ties go to the smaller id: the map is ordered by it.
    if (!next || count < fewest) {
      next = key;
      fewest = count;
    }
  }
  return next;
}

void GlobalSearchQueue::Served(PoseKey key, int searches) {
  const auto it = waiting_.find(key.trajectory);
  if (it != waiting_.end() && it->second == key) waiting_.erase(it);
  tokens_ -= searches;
  searched_[key.trajectory] += searches;
  searches_ += searches;
}

int64_t GlobalSearchQueue::Searched(TrajectoryId query) const {
  const auto it = searched_.find(query);
  return it == searched_.end() ? 0 : it->second;
}

int64_t GlobalSearchQueue::PairSearches(TrajectoryId query, TrajectoryId other) const {
  const auto it = pair_searched_.find({query, other});
  return it == pair_searched_.end() ? 0 : it->second;
}

void GlobalSearchQueue::CountPair(TrajectoryId query, TrajectoryId other, int searches) {
  pair_searched_[{query, other}] += searches;
}

}  // namespace anchormap
