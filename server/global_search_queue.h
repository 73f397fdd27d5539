#pragma once
// The budget of the first-join (global) searches of ScanEncounters (issue 12). A global
// search matches one keyframe against one submap of a trajectory not yet in its frame,
// over every heading and the submap's whole grid: it is the costliest match the server
// runs, and without a bound a team of N unjoined robots costs N - 1 searches per keyframe
// (100 robots: 7 s of data took 20-55 min). Here the work is bounded independently of the
// number of robots and trajectories:
// - in data time, by a token bucket of searches_per_s (one token = one submap searched),
//   saving at most burst tokens: the same input spends the same tokens, so the offline
//   replay stays deterministic;
// - fairly: each trajectory waits with its newest eligible keyframe (a newer one replaces
//   it: it sees as much of the place), and the waiting trajectory searched least so far is
//   served first; ScanEncounters picks its targets among the other groups, the pairs of
//   trajectories searched least first.
// Two robots never run out of tokens (they search as before the budget).

#include <cstdint>
#include <map>
#include <optional>
#include <utility>

#include "common/solver/keys.h"
#include "common/util/status.h"

namespace anchormap {

struct GlobalSearchBudgetOptions {
  // Submaps searched per second of data, over the whole team. A search of a simulated
  // office submap costs ~150 ms of CPU (30 robots x 60 s: 256 searches at 4/s against 91 at
  // 1/s cost 24.5 s more): 1 per second keeps the whole team's first-join work near a
  // seventh of a core. Two robots ask less (Intel split in two: 0.18/s) and search as
  // before the budget; three unjoined simulated robots ask ~2.3/s and wait once the burst
  // is spent.
  double searches_per_s = 1.0;
  // Most tokens saved up (also the start): a burst of joins at the start of a small run.
  double burst = 40.0;

  Status Validate() const;
};

class GlobalSearchQueue {
 public:
  explicit GlobalSearchQueue(const GlobalSearchBudgetOptions& options = {})
      : options_(options), tokens_(options.burst) {}

  // Data time advanced to now_utime (never goes back): tokens accrue.
  void Advance(int64_t now_utime);
  // `key` waits for a global search; an older waiting keyframe of its trajectory is dropped.
  void Enqueue(PoseKey key);
  // The waiting keyframe to serve next: its trajectory has the fewest searches so far
  // (then the smaller id). nullopt when none waits.
  std::optional<PoseKey> Next() const;
  bool CanAfford(int searches) const { return tokens_ >= searches; }
  // `key` (from Next) leaves the queue, having searched `searches` submaps (0: it had no
  // target left); its tokens are spent.
  void Served(PoseKey key, int searches);
  // Searches so far of (query trajectory, other trajectory), for the fair choice of targets.
  int64_t PairSearches(TrajectoryId query, TrajectoryId other) const;
  void CountPair(TrajectoryId query, TrajectoryId other, int searches);

  // Searches so far of the keyframes of `query`.
  int64_t Searched(TrajectoryId query) const;
  size_t waiting() const { return waiting_.size(); }
  int64_t searches() const { return searches_; }
  // Keyframes replaced by a newer one of their trajectory before being served.
  int64_t dropped() const { return dropped_; }

  // The queue as plain values (snapshots: server/scan_encounter_state.h).
  struct State {
    double tokens = 0.0;
    std::optional<int64_t> last_utime;
    std::map<TrajectoryId, PoseKey> waiting;
    std::map<TrajectoryId, int64_t> searched;
    std::map<std::pair<TrajectoryId, TrajectoryId>, int64_t> pair_searched;
    int64_t searches = 0;
    int64_t dropped = 0;
  };
  State ExportState() const {
    return {tokens_, last_utime_, waiting_, searched_, pair_searched_, searches_, dropped_};
  }
  void ImportState(State s) {
    tokens_ = s.tokens;
    last_utime_ = s.last_utime;
    waiting_ = std::move(s.waiting);
    searched_ = std::move(s.searched);
    pair_searched_ = std::move(s.pair_searched);
    searches_ = s.searches;
    dropped_ = s.dropped;
  }

 private:
  GlobalSearchBudgetOptions options_;
  double tokens_;
  std::optional<int64_t> last_utime_;
  std::map<TrajectoryId, PoseKey> waiting_;
  std::map<TrajectoryId, int64_t> searched_;  // by query trajectory
  std::map<std::pair<TrajectoryId, TrajectoryId>, int64_t> pair_searched_;
  int64_t searches_ = 0;
  int64_t dropped_ = 0;
};

}  // namespace anchormap
