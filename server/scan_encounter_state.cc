// ScanEncounters::ExportState / ImportState (scan_encounter_state.h).

#include "server/scan_encounter_state.h"

#include "server/scan_encounters.h"

namespace anchormap {
ScanEncounterState ScanEncounters::ExportState() const {
  ScanEncounterState s;
  matches_.ExportState(&s);
  s.waiting.assign(waiting_.begin(), waiting_.end());
  submaps_.ExportState(&s);
  s.global_cursor = global_cursor_;
  s.global_queue = global_queue_.ExportState();
  qualifier_.ExportState(&s);
  s.now_utime = now_utime_;
  s.near_quiet_until = near_quiet_until_;
  for (const auto& [trajectory, entry] : near_index_) {
    s.near_index[trajectory] = {entry.index.Entries(), entry.indexed, entry.refreshed_utime,
                                entry.merges};
  }
  s.stats = stats_;
  s.near_budget = near_budget_.ExportState();
  for (const auto& [pair, held] : near_held_) {
    auto& out = s.near_held[pair];
    for (const EncounterCandidate& c : held) out.push_back(ToState(c));
  }
  s.near_joined = near_joined_;
  s.near_joined_known = near_joined_known_;
  return s;
}

void ScanEncounters::ImportState(const ScanEncounterState& s) {
  matches_.ImportState(s);
  waiting_.assign(s.waiting.begin(), s.waiting.end());
  submaps_.ImportState(s);
  global_cursor_ = s.global_cursor;
  global_queue_.ImportState(s.global_queue);
  qualifier_.ImportState(s);
  now_utime_ = s.now_utime;
  near_quiet_until_ = s.near_quiet_until;
  near_index_.clear();
  for (const auto& [trajectory, entry] : s.near_index) {
    SubmapIndex& out = near_index_[trajectory];
    for (const auto& [item, position] : entry.entries) out.index.Add(item, position);
    out.indexed = entry.indexed;
    out.refreshed_utime = entry.refreshed_utime;
    out.merges = entry.merges;
  }
  stats_ = s.stats;
  if (s.near_budget) near_budget_.ImportState(*s.near_budget);
  near_held_.clear();
  for (const auto& [pair, held] : s.near_held) {
    std::deque<EncounterCandidate>& out = near_held_[pair];
    for (const ScanEncounterCandidateState& c : held) out.push_back(FromState(c));
  }
  near_joined_ = s.near_joined;
  near_joined_known_ = s.near_joined_known;
  caught_up_frames_.clear();
  looked_back_frames_.clear();
}

}  // namespace anchormap
