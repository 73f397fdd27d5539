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

std::shared_future<std::optional<MatchResult>> MatchPool::Submit(const MatchTag& tag, Job job) {
  const int64_t ordinal = next_ordinal_++;
  ++stats_.submitted;
  if (const auto found = preloaded_.find(ordinal); found != preloaded_.end()) {
    const RecordedMatch recorded = std::move(found->second);
    preloaded_.erase(found);
    if (recorded.options_fingerprint != options_fingerprint_) {
      ++stats_.other_options;
    } else if (recorded.tag == tag) {
      ++stats_.reused;
      std::promise<std::optional<MatchResult>> done;
      done.set_value(recorded.result);
      return done.get_future().share();
    } else {
      ++stats_.mismatched;
    }
  }
  // The result is recorded (journaled) before the future is ready, hence before it is used.
  std::packaged_task<std::optional<MatchResult>()> task(
      [this, ordinal, tag, fingerprint = options_fingerprint_,
       job = std::move(job)]() -> std::optional<MatchResult> {
        RecordedMatch recorded{ordinal, tag, fingerprint, job()};
        Record(recorded);
        return std::move(recorded.result);
      });
  std::shared_future<std::optional<MatchResult>> result = task.get_future().share();
  if (threads_.empty()) {
    task();
    return result;
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    queue_.push_back(std::move(task));
    ++outstanding_;
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
    std::lock_guard<std::mutex> lock(mutex_);
    if (--outstanding_ == 0) idle_.notify_all();
  }
}

void MatchPool::WaitIdle() {
  std::unique_lock<std::mutex> lock(mutex_);
  idle_.wait(lock, [this] { return outstanding_ == 0; });
}

void MatchPool::Preload(const std::vector<RecordedMatch>& recorded) {
  for (const RecordedMatch& match : recorded) {
    if (match.ordinal >= next_ordinal_) preloaded_[match.ordinal] = match;
  }
}

void MatchPool::SetRecorder(Recorder recorder) {
  std::lock_guard<std::mutex> lock(record_mutex_);
  recorder_ = std::move(recorder);
}

void MatchPool::Record(const RecordedMatch& match) {
  std::lock_guard<std::mutex> lock(record_mutex_);
  if (recorder_) recorder_(match);
}

std::shared_future<std::optional<MatchResult>> RunMatch(MatchPool* pool, const MatchTag& tag,
                                                        MatchPool::Job job) {
  if (pool) return pool->Submit(tag, std::move(job));
  std::promise<std::optional<MatchResult>> done;
  done.set_value(job());
  return done.get_future().share();
}

std::shared_future<std::optional<MatchResult>> ReadyMatch(std::optional<MatchResult> result) {
  std::promise<std::optional<MatchResult>> promise;
  promise.set_value(std::move(result));
  return promise.get_future().share();
}

}  // namespace anchormap
