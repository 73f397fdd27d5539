// LoopClosures::ExportState / ImportState (loop_closure_state.h).

#include "server/loop_closure_state.h"

#include "server/loop_closures.h"

namespace anchormap {

LoopClosureState LoopClosures::ExportState() const {
  LoopClosureState s;
  for (const PendingMatch& m : matches_) {
    LoopClosureState::Match out;
    out.due_utime = m.due_utime;
    out.candidate = m.candidate;
    out.key = m.key;
    out.key_utime = m.key_utime;
    out.predicted = m.predicted;
    out.wide = m.wide;
    out.drift = m.drift;
    if (m.query) out.query = *m.query;
    out.submap_poses = m.submap_poses;
    out.result = m.result.get();  // waits for a match in flight
    out.has_rival = m.rival.valid();
    if (out.has_rival) out.rival = m.rival.get();
    s.matches.push_back(std::move(out));
  }
  s.now_utime = now_utime_;
  s.waiting.assign(waiting_.begin(), waiting_.end());
  s.quiet_until = quiet_until_;
  s.next_wide = next_wide_;
  for (const auto& [trajectory, hypotheses] : kept_) {
    std::vector<LoopClosureState::Hypothesis>& out = s.kept[trajectory];
    for (const Hypothesis& h : hypotheses) {
      out.push_back({h.candidate, h.key, h.measured, h.covariance, h.key_utime, h.weak});
    }
  }
  s.last_closure = last_closure_;
  s.entered = entered_;
  s.stats = stats_;
  s.wide_searches = wide_searches_;
  s.ambiguous = ambiguous_;
  s.budget = budget_.ExportState();
  s.folded = folded_;
  return s;
}

void LoopClosures::ImportState(const LoopClosureState& s) {
  matches_.clear();
  for (const LoopClosureState::Match& m : s.matches) {
    PendingMatch pending;
    pending.due_utime = m.due_utime;
    pending.candidate = m.candidate;
    pending.key = m.key;
    pending.key_utime = m.key_utime;
    pending.predicted = m.predicted;
    pending.wide = m.wide;
    pending.drift = m.drift;
    if (m.wide) pending.query = std::make_shared<const PointCloud>(m.query);
    pending.submap_poses = m.submap_poses;
    pending.result = ReadyMatch(m.result);
    if (m.has_rival) pending.rival = ReadyMatch(m.rival);
    matches_.push_back(std::move(pending));
  }
  now_utime_ = s.now_utime;
  waiting_.assign(s.waiting.begin(), s.waiting.end());
  quiet_until_ = s.quiet_until;
  next_wide_ = s.next_wide;
  kept_.clear();
  for (const auto& [trajectory, hypotheses] : s.kept) {
    std::deque<Hypothesis>& out = kept_[trajectory];
    for (const LoopClosureState::Hypothesis& h : hypotheses) {
      out.push_back({h.candidate, h.key, h.measured, h.covariance, h.key_utime, h.weak});
    }
  }
  last_closure_ = s.last_closure;
  entered_ = s.entered;
  stats_ = s.stats;
  wide_searches_ = s.wide_searches;
  ambiguous_ = s.ambiguous;
  if (s.budget) budget_.ImportState(*s.budget);
  folded_ = s.folded;
}

}  // namespace anchormap
