#pragma once
// The scan encounters' matches in flight: each runs on the MatchPool's workers (or on the
// caller's thread without a pool) and is used when the canonical input reaches its keyframe's
// time plus the schedule's lag, in the order the matches were made, waiting for it if needed:
// deterministic, whatever the worker count.

#include <cstddef>
#include <cstdint>
#include <deque>
#include <future>
#include <optional>

#include "common/scan_matching/correlative_matcher.h"
#include "common/solver/keys.h"
#include "server/match_pool.h"
#include "server/scan_encounter_state.h"

namespace anchormap {

class EncounterMatches {
 public:
  struct Pending {
    int64_t due_utime = 0;
    PoseKey key;     // the query keyframe
    PoseKey center;  // the other trajectory's submap
    bool global = false;
    bool wide = false;  // a near search's window wider than max_window_m
    int64_t key_utime = 0;
    std::shared_future<std::optional<MatchResult>> result;
  };

  EncounterMatches(MatchPool* pool, MatchSchedule schedule) : pool_(pool), schedule_(schedule) {}

  // Hands a match of keyframe `key` against the submap around `center` to the pool (used
  // lag_s after key_utime, or after `due_from_utime` when given: a past keyframe's).
  void Submit(PoseKey key, PoseKey center, bool global, bool wide, int64_t key_utime,
              MatchPool::Job job, std::optional<int64_t> due_from_utime = std::nullopt);
  // The oldest match, taken out, when it is due at `now_utime` (or whatever its time when
  // `all`); nullopt when there is none.
  std::optional<Pending> NextDue(bool all, int64_t now_utime);
  size_t size() const { return matches_.size(); }

  // Snapshots: ExportState waits for the matches in flight.
  void ExportState(ScanEncounterState* s) const;
  void ImportState(const ScanEncounterState& s);

 private:
  MatchPool* pool_;
  MatchSchedule schedule_;
  std::deque<Pending> matches_;
};

}  // namespace anchormap
