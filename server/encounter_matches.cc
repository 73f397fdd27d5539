#include "server/encounter_matches.h"

#include <limits>
#include <utility>

namespace anchormap {

void EncounterMatches::Submit(PoseKey key, PoseKey center, bool global, bool wide,
                              int64_t key_utime, MatchPool::Job job,
                              std::optional<int64_t> due_from_utime) {
  Pending pending;
  pending.key = key;
  pending.center = center;
  pending.global = global;
  pending.wide = wide;
  pending.key_utime = key_utime;
  pending.due_utime = pool_ ? schedule_.DueUtime(due_from_utime.value_or(key_utime))
                            : std::numeric_limits<int64_t>::min();
  pending.result =
      RunMatch(pool_, MatchTag{key, center, global ? MatchKind::kScanGlobal : MatchKind::kScanNear},
               std::move(job));
  matches_.push_back(std::move(pending));
}

std::optional<EncounterMatches::Pending> EncounterMatches::NextDue(bool all, int64_t now_utime) {
  if (matches_.empty() || !(all || matches_.front().due_utime <= now_utime)) return std::nullopt;
  Pending pending = std::move(matches_.front());
  matches_.pop_front();
  return pending;
}

void EncounterMatches::ExportState(ScanEncounterState* s) const {
  for (const Pending& m : matches_) {
    // Waits for a match in flight.
    s->matches.push_back(
        {m.due_utime, m.key, m.center, m.global, m.wide, m.key_utime, m.result.get()});
  }
}

void EncounterMatches::ImportState(const ScanEncounterState& s) {
  matches_.clear();
  for (const ScanEncounterState::Match& m : s.matches) {
    Pending pending;
    pending.due_utime = m.due_utime;
    pending.key = m.key;
    pending.center = m.center;
    pending.global = m.global;
    pending.wide = m.wide;
    pending.key_utime = m.key_utime;
    pending.result = ReadyMatch(m.result);
    matches_.push_back(std::move(pending));
  }
}

}  // namespace anchormap
