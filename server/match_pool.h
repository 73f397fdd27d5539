#pragma once
// The worker threads of the server's scan-matching sources (issue 11, item 6). A source
// hands the pool a job that reads only what the job owns (a point cloud, a shared immutable
// ScanReference, a predicted pose) and gets a future; it uses the result at a fixed point
// of the canonical input (MatchSchedule), waiting for it if the job is not done, so that
// what the server accepts never depends on thread timing or on the number of workers.
// With 0 workers a job runs at once on the caller's thread (the same results).
//
// Crash recovery (docs/ARCHITECTURE.md "Scan sources in the journal"): every job gets an
// ordinal when it is submitted (the sources submit on the server's thread, in the canonical
// input's order, so a replay of the same journal submits the same jobs in the same order)
// and its result is handed to a recorder (the server's journal) before it is used. A
// restart preloads the journaled results: a job whose ordinal and tag match one is not run
// again, its recorded result is returned. The sources' logic runs as it did live on the same
// results, so their decisions and their state (kept candidates, hypotheses, budgets) are
// rebuilt exactly, without the matching's cost.

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include "common/scan_matching/correlative_matcher.h"
#include "common/solver/keys.h"

namespace anchormap {

// When a source uses a match: once the canonical input has reached the query keyframe's
// time plus lag_s (data time), i.e. at the source's first Poll at or after it.
struct MatchSchedule {
  double lag_s = 0.0;
  int64_t DueUtime(int64_t keyframe_utime) const {
    return keyframe_utime + static_cast<int64_t>(1e6 * lag_s);
  }
};

// Which of the sources' searches a job is: two jobs on the same two keyframes (a loop
// closure's wide search and the local match its ambiguity test compares it with) are told
// apart. kUnknown: a result journaled before kinds were recorded (codec version 1).
enum class MatchKind : uint8_t {
  kUnknown = 0,
  kLoopLocal = 1,   // a loop closure's window search around the prediction
  kLoopWide = 2,    // a loop closure's wide (branch-and-bound) search
  kLoopRival = 3,   // the wide search's ambiguity test: the local window it competes with
  kScanNear = 4,    // a scan encounter's window search near the prediction
  kScanGlobal = 5,  // a scan encounter's global search
};
constexpr uint8_t kLastMatchKind = 5;

// What a match is of: the query keyframe, the reference's keyframe (a submap's centre, a
// loop-closure candidate) and the kind of search. A recorded result is reused only for the
// same ordinal and tag, so a journal replayed with other options (other jobs) recomputes
// instead of mixing up.
struct MatchTag {
  PoseKey query;
  PoseKey reference;
  MatchKind kind = MatchKind::kUnknown;
  bool operator==(const MatchTag& o) const {
    return query == o.query && reference == o.reference && kind == o.kind;
  }
};

// One job's result, as journaled.
struct RecordedMatch {
  int64_t ordinal = 0;  // the pool's submission count before it
  MatchTag tag;
  // The options it was computed under (MatchOptionsFingerprint; 0: not recorded, an older
  // journal): a result is reused only under the same.
  uint64_t options_fingerprint = 0;
  std::optional<MatchResult> result;
};

struct MatchPoolStats {
  int64_t submitted = 0;
  int64_t reused = 0;      // served from preloaded results (not run)
  int64_t mismatched = 0;  // a preloaded result with the ordinal but another tag (run)
  // A preloaded result with the ordinal but computed under other options, or under options
  // not recorded (an older journal): run again.
  int64_t other_options = 0;
};

class MatchPool {
 public:
  using Job = std::function<std::optional<MatchResult>()>;
  // Called with each computed result before its future is ready (so before it is used), on
  // the thread that ran the job; calls are serialised by the pool.
  using Recorder = std::function<void(const RecordedMatch&)>;

  explicit MatchPool(int workers);
  ~MatchPool();
  MatchPool(const MatchPool&) = delete;
  MatchPool& operator=(const MatchPool&) = delete;

  std::shared_future<std::optional<MatchResult>> Submit(const MatchTag& tag, Job job);
  int workers() const { return static_cast<int>(threads_.size()); }

  // Results to serve instead of running their jobs (a restart's journal). Reused results
  // are not recorded again (they are in the journal already).
  void Preload(const std::vector<RecordedMatch>& recorded);
  // Null: nothing recorded. Jobs already running record with the recorder set when they end.
  void SetRecorder(Recorder recorder);
  // The options the results are computed under (stamped on every record; only records
  // with the same are reused). Set before the first Submit.
  void SetOptionsFingerprint(uint64_t fingerprint) { options_fingerprint_ = fingerprint; }
  uint64_t options_fingerprint() const { return options_fingerprint_; }
  // Preloaded results not (yet) used.
  size_t preloaded() const { return preloaded_.size(); }
  const MatchPoolStats& stats() const { return stats_; }
  // The ordinal the next job gets. A server restored from a snapshot continues the
  // numbering where the snapshot's server was (ContinueAt), so the jobs after it meet their
  // journaled results.
  int64_t next_ordinal() const { return next_ordinal_; }
  // Waits until every job handed to the workers has ended (its result recorded). Jobs are
  // submitted from the server's thread only, so a caller on it then has no match in flight
  // (a snapshot: server/node/server_journal.cc takes it without holding the journal's lock,
  // which the recorder needs).
  void WaitIdle();
  void ContinueAt(int64_t ordinal) { next_ordinal_ = ordinal; }

 private:
  void Work();
  void Record(const RecordedMatch& match);

  int64_t next_ordinal_ = 0;
  uint64_t options_fingerprint_ = 0;
  std::map<int64_t, RecordedMatch> preloaded_;  // by ordinal; the server's thread only
  MatchPoolStats stats_;
  std::mutex record_mutex_;
  Recorder recorder_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable idle_;
  int64_t outstanding_ = 0;  // handed to the workers and not ended (under mutex_)
  std::deque<std::packaged_task<std::optional<MatchResult>()>> queue_;
  bool stopping_ = false;
  std::vector<std::thread> threads_;
};

// A result already known (a snapshot's match in flight) as the future a job would give.
std::shared_future<std::optional<MatchResult>> ReadyMatch(std::optional<MatchResult> result);

// Runs `job` on `pool`, or at once on the caller's thread when there is no pool (the
// sources' 0-worker mode): either way the caller gets a future of its result.
std::shared_future<std::optional<MatchResult>> RunMatch(MatchPool* pool, const MatchTag& tag,
                                                        MatchPool::Job job);

}  // namespace anchormap
