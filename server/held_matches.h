#pragma once
// Matches that enter the graph only with a second one that agrees (a wide loop closure, a
// wide near match between drifted trajectories) wait in a short queue per trajectory or
// pair, oldest first. The queue is bounded in length and in how many query keyframes a match
// may wait; whatever leaves it without a partner is counted as unconfirmed, so that the
// sources' stats lines add up (kept = what waits now).

#include <cstdint>
#include <deque>
#include <utility>

#include "server/candidate_stats.h"

namespace anchormap {

// Gives up, oldest first, the held matches whose query keyframe lies more than `max_gap`
// keyframes before `index`; `index_of(match)` is a match's query keyframe index.
template <typename Match, typename IndexOf>
void GiveUpHeldOlderThan(int index, int max_gap, IndexOf index_of, std::deque<Match>* held,
                         CandidateStats* stats) {
  while (!held->empty() && index - index_of(held->front()) > max_gap) {
    held->pop_front();
    --stats->kept;
    ++stats->unconfirmed;
  }
}

// Holds `match` behind the others; beyond `max_held` the oldest is given up.
template <typename Match>
void Hold(Match match, int max_held, std::deque<Match>* held, CandidateStats* stats) {
  held->push_back(std::move(match));
  ++stats->kept;
  if (static_cast<int>(held->size()) > max_held) {
    held->pop_front();
    --stats->kept;
    ++stats->unconfirmed;
  }
}

// A pair entered: the others held with it were made against the estimate before, and are
// dropped (neither accepted nor refused).
template <typename Match>
void DropHeld(std::deque<Match>* held, CandidateStats* stats) {
  stats->kept -= static_cast<int64_t>(held->size());
  held->clear();
}

// End of input: every held match is given up.
template <typename Match>
void GiveUpHeld(std::deque<Match>* held, CandidateStats* stats) {
  stats->unconfirmed += static_cast<int64_t>(held->size());
  DropHeld(held, stats);
}

}  // namespace anchormap
