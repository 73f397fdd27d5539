#include "server/match_pool.h"

#include <utility>

namespace anchormap {

MatchPool::MatchPool(int workers) {
  for (int i = 0; i < workers; ++i) threads_.emplace_back([this] { Work(); });
}

MatchPool::~MatchPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  for (std::thread& thread : threads_) thread.join();
}

std::shared_future<std::optional<MatchResult>> MatchPool::Submit(Job job) {
  std::packaged_task<std::optional<MatchResult>()> task(std::move(job));
  std::shared_future<std::optional<MatchResult>> result = task.get_future().share();
  if (threads_.empty()) {
    task();
    return result;
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    queue_.push_back(std::move(task));
  }
  wake_.notify_one();
  return result;
}

void MatchPool::Work() {
  for (;;) {
    std::packaged_task<std::optional<MatchResult>()> task;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [this] { return stopping_ || !queue_.empty(); });
      // Jobs still queued at shutdown run anyway: a waiting future must not be broken.
      if (queue_.empty()) return;
      task = std::move(queue_.front());
      queue_.pop_front();
    }
    task();
  }
}

std::shared_future<std::optional<MatchResult>> RunMatch(MatchPool* pool, MatchPool::Job job) {
  if (pool) return pool->Submit(std::move(job));
  std::promise<std::optional<MatchResult>> done;
  done.set_value(job());
  return done.get_future().share();
}

}  // namespace anchormap
