#include "server/source_state_codec.h"

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "server/match_pool.h"
#include "server/recorded_match_codec.h"

namespace anchormap {
namespace {

using Pair = std::pair<TrajectoryId, TrajectoryId>;

void Put(ByteWriter* w, TrajectoryId t) { w->I64(t.value()); }
void Get(ByteReader* r, TrajectoryId* t) { *t = TrajectoryId(r->I64()); }
void Put(ByteWriter* w, const PoseKey& k) {
  w->I64(k.trajectory.value());
  w->I32(k.index);
}
void Get(ByteReader* r, PoseKey* k) {
  k->trajectory = TrajectoryId(r->I64());
  k->index = r->I32();
}
void Put(ByteWriter* w, const Pair& p) {
  Put(w, p.first);
  Put(w, p.second);
}
void Get(ByteReader* r, Pair* p) {
  Get(r, &p->first);
  Get(r, &p->second);
}
void Put(ByteWriter* w, int32_t v) { w->I32(v); }
void Get(ByteReader* r, int32_t* v) { *v = r->I32(); }
void Put(ByteWriter* w, int64_t v) { w->I64(v); }
void Get(ByteReader* r, int64_t* v) { *v = r->I64(); }
void Put(ByteWriter* w, size_t v) { w->Size(v); }
void Get(ByteReader* r, size_t* v) { *v = static_cast<size_t>(r->Raw<uint64_t>()); }
void Put(ByteWriter* w, const std::pair<int32_t, int32_t>& p) {
  w->I32(p.first);
  w->I32(p.second);
}
void Get(ByteReader* r, std::pair<int32_t, int32_t>* p) {
  p->first = r->I32();
  p->second = r->I32();
}

// Maps with keys and values of the kinds above: a count, then the pairs.
void Put(ByteWriter* w, const MatchBudget::Ledger& l) {
  w->F64(l.driven_m);
  w->I64(l.skips);
}
void Get(ByteReader* r, MatchBudget::Ledger* l) {
  l->driven_m = r->F64();
  l->skips = r->I64();
}

template <typename Map>
void PutMap(ByteWriter* w, const Map& map) {
  w->Size(map.size());
  for (const auto& [key, value] : map) {
    Put(w, key);
    Put(w, value);
  }
}
template <typename Map>
void GetMap(ByteReader* r, Map* map) {
  map->clear();
  for (size_t i = 0, n = r->Count(); i < n && !r->failed(); ++i) {
    typename Map::key_type key{};
    typename Map::mapped_type value{};
    Get(r, &key);
    Get(r, &value);
    map->emplace(std::move(key), std::move(value));
  }
}

// A token bucket's level and clock (the global searches' queue, the matching budgets).
void PutTokens(ByteWriter* w, double tokens, const std::optional<int64_t>& last_utime) {
  w->F64(tokens);
  w->Bool(last_utime.has_value());
  w->I64(last_utime.value_or(0));
}
void GetTokens(ByteReader* r, double* tokens, std::optional<int64_t>* last_utime) {
  *tokens = r->F64();
  const bool has_last = r->Bool();
  const int64_t last = r->I64();
  last_utime->reset();
  if (has_last) *last_utime = last;
}

// A matching budget (version 9 on).
void PutBudget(ByteWriter* w, uint32_t snapshot_version,
               const std::optional<MatchBudget::State>& budget) {
  if (snapshot_version < 9) return;
  w->Bool(budget.has_value());
  if (!budget) return;
  PutTokens(w, budget->tokens, budget->last_utime);
  PutMap(w, budget->ledgers);
  w->F64(budget->spent);
  w->I64(budget->skipped);
}
void GetBudget(ByteReader* r, uint32_t snapshot_version,
               std::optional<MatchBudget::State>* budget) {
  budget->reset();
  if (snapshot_version < 9 || !r->Bool()) return;
  MatchBudget::State b;
  GetTokens(r, &b.tokens, &b.last_utime);
  GetMap(r, &b.ledgers);
  b.spent = r->F64();
  b.skipped = r->I64();
  *budget = std::move(b);
}

void PutKeys(ByteWriter* w, const std::vector<PoseKey>& keys) {
  w->Size(keys.size());
  for (const PoseKey& k : keys) Put(w, k);
}
void GetKeys(ByteReader* r, std::vector<PoseKey>* keys) {
  keys->resize(r->Count(12));
  for (PoseKey& k : *keys) Get(r, &k);
}

// A match result as its journal record holds it (every field, bit for bit).
void PutResult(ByteWriter* w, const std::optional<MatchResult>& result) {
  RecordedMatch record;
  record.tag.kind = MatchKind::kLoopLocal;  // any valid kind: only the result is read back
  record.result = result;
  const std::vector<uint8_t> bytes = EncodeRecordedMatch(record);
  w->Size(bytes.size());
  for (uint8_t b : bytes) w->U8(b);
}
void GetResult(ByteReader* r, std::optional<MatchResult>* result) {
  std::vector<uint8_t> bytes(r->Count());
  for (uint8_t& b : bytes) b = r->U8();
  if (r->failed()) return;
  Result<RecordedMatch> record = DecodeRecordedMatch(bytes.data(), bytes.size());
  if (!record.ok()) {
    r->Fail();
    return;
  }
  *result = std::move(record->result);
}

void Put(ByteWriter* w, const CandidateStats& s) {
  for (int64_t v : {s.candidates, s.accepted, s.no_match, s.weak_match, s.gate_rejected, s.kept,
                    s.unconfirmed, s.repeated}) {
    w->I64(v);
  }
}
void Get(ByteReader* r, CandidateStats* s) {
  for (int64_t* v : {&s->candidates, &s->accepted, &s->no_match, &s->weak_match, &s->gate_rejected,
                     &s->kept, &s->unconfirmed, &s->repeated}) {
    *v = r->I64();
  }
}
static_assert(sizeof(CandidateStats) == 8 * 8, "CandidateStats changed: update the codec");

void PutCandidate(ByteWriter* w, const ScanEncounterCandidateState& c) {
  Put(w, c.a);
  Put(w, c.b);
  w->Pose(c.T_a_b);
  w->Matrix(c.covariance);
  w->I64(c.utime);
  w->Bool(c.a_is_query);
}

void GetCandidate(ByteReader* r, ScanEncounterCandidateState* c) {
  Get(r, &c->a);
  Get(r, &c->b);
  c->T_a_b = r->Pose();
  c->covariance = r->Matrix();
  c->utime = r->I64();
  c->a_is_query = r->Bool();
}

}  // namespace

void PutLoopClosureState(ByteWriter* w, uint32_t snapshot_version, const LoopClosureState& s) {
  w->Size(s.matches.size());
  for (const LoopClosureState::Match& m : s.matches) {
    w->I64(m.due_utime);
    Put(w, m.candidate);
    Put(w, m.key);
    w->I64(m.key_utime);
    w->Pose(m.predicted.T_a_b);
    w->Matrix(m.predicted.covariance);
    w->Bool(m.wide);
    w->Matrix(m.drift);
    w->Size(m.query.size());
    for (const Eigen::Vector2d& p : m.query) {
      w->F64(p.x());
      w->F64(p.y());
    }
    w->Size(m.submap_poses.size());
    for (const auto& [index, pose] : m.submap_poses) {
      w->I32(index);
      w->Pose(pose);
    }
    PutResult(w, m.result);
    w->Bool(m.has_rival);
    if (m.has_rival) PutResult(w, m.rival);
  }
  w->I64(s.now_utime);
  PutKeys(w, s.waiting);
  PutMap(w, s.quiet_until);
  PutMap(w, s.next_wide);
  w->Size(s.kept.size());
  for (const auto& [trajectory, hypotheses] : s.kept) {
    Put(w, trajectory);
    w->Size(hypotheses.size());
    for (const LoopClosureState::Hypothesis& h : hypotheses) {
      Put(w, h.candidate);
      Put(w, h.key);
      w->Pose(h.measured);
      w->Matrix(h.covariance);
      w->I64(h.key_utime);
      if (snapshot_version >= 3) w->Bool(h.weak);  // before version 3 none was weak
    }
  }
  PutMap(w, s.last_closure);
  w->Size(s.entered.size());
  for (const auto& [trajectory, pairs] : s.entered) {
    Put(w, trajectory);
    w->Size(pairs.size());
    for (const auto& p : pairs) Put(w, p);
  }
  Put(w, s.stats);
  w->I64(s.wide_searches);
  w->I64(s.ambiguous);
  PutBudget(w, snapshot_version, s.budget);
  if (snapshot_version >= 12) w->I64(s.folded);
}

void GetLoopClosureState(ByteReader* r, uint32_t snapshot_version, LoopClosureState* s) {
  s->matches.resize(r->Count(8));
  for (LoopClosureState::Match& m : s->matches) {
    m.due_utime = r->I64();
    Get(r, &m.candidate);
    Get(r, &m.key);
    m.key_utime = r->I64();
    m.predicted.T_a_b = r->Pose();
    m.predicted.covariance = r->Matrix();
    m.wide = r->Bool();
    m.drift = r->Matrix();
    m.query.resize(r->Count(2 * sizeof(double)));
    for (Eigen::Vector2d& p : m.query) {
      const double x = r->F64();
      p = Eigen::Vector2d(x, r->F64());
    }
    m.submap_poses.resize(r->Count(sizeof(int32_t) + 3 * sizeof(double)));
    for (auto& [index, pose] : m.submap_poses) {
      index = r->I32();
      pose = r->Pose();
    }
    GetResult(r, &m.result);
    m.has_rival = r->Bool();
    if (m.has_rival) GetResult(r, &m.rival);
  }
  s->now_utime = r->I64();
  GetKeys(r, &s->waiting);
  GetMap(r, &s->quiet_until);
  GetMap(r, &s->next_wide);
  s->kept.clear();
  for (size_t i = 0, n = r->Count(); i < n && !r->failed(); ++i) {
    TrajectoryId trajectory(0);
    Get(r, &trajectory);
    std::vector<LoopClosureState::Hypothesis>& hypotheses = s->kept[trajectory];
    hypotheses.resize(r->Count(8));
    for (LoopClosureState::Hypothesis& h : hypotheses) {
      Get(r, &h.candidate);
      Get(r, &h.key);
      h.measured = r->Pose();
      h.covariance = r->Matrix();
      h.key_utime = r->I64();
      h.weak = snapshot_version >= 3 && r->Bool();  // before version 3 none was weak
    }
  }
  GetMap(r, &s->last_closure);
  s->entered.clear();
  for (size_t i = 0, n = r->Count(); i < n && !r->failed(); ++i) {
    TrajectoryId trajectory(0);
    Get(r, &trajectory);
    auto& pairs = s->entered[trajectory];
    for (size_t j = 0, m = r->Count(8); j < m && !r->failed(); ++j) {
      std::pair<int32_t, int32_t> p;
      Get(r, &p);
      pairs.insert(p);
    }
  }
  Get(r, &s->stats);
  s->wide_searches = r->I64();
  s->ambiguous = r->I64();
  GetBudget(r, snapshot_version, &s->budget);
  s->folded = snapshot_version >= 12 ? r->I64() : 0;
}

void PutScanEncounterState(ByteWriter* w, uint32_t snapshot_version, const ScanEncounterState& s) {
  w->Size(s.matches.size());
  for (const ScanEncounterState::Match& m : s.matches) {
    w->I64(m.due_utime);
    Put(w, m.key);
    Put(w, m.center);
    w->Bool(m.global);
    if (snapshot_version >= 5) w->Bool(m.wide);  // before version 5 none was wide
    w->I64(m.key_utime);
    PutResult(w, m.result);
  }
  PutKeys(w, s.waiting);
  w->Size(s.submaps.size());
  for (const auto& [trajectory, submaps] : s.submaps) {
    Put(w, trajectory);
    w->Size(submaps.size());
    for (const auto& [center, drawing] : submaps) {
      Put(w, center);
      Put(w, drawing.center);
      w->Size(drawing.T_center_keyframes.size());
      for (const auto& [index, pose] : drawing.T_center_keyframes) {
        w->I32(index);
        w->Pose(pose);
      }
      w->Size(drawing.num_points);
    }
  }
  PutMap(w, s.global_cursor);
  const GlobalSearchQueue::State& q = s.global_queue;
  PutTokens(w, q.tokens, q.last_utime);
  w->Size(q.waiting.size());
  for (const auto& [trajectory, key] : q.waiting) {
    Put(w, trajectory);
    Put(w, key);
  }
  PutMap(w, q.searched);
  PutMap(w, q.pair_searched);
  w->I64(q.searches);
  w->I64(q.dropped);
  w->Size(s.kept.size());
  for (const auto& [pair, kept] : s.kept) {
    Put(w, pair);
    w->Size(kept.size());
    for (const ScanEncounterState::Kept& k : kept) {
      PutCandidate(w, k.candidate);
      w->I32(k.support);
      w->Bool(k.localised);
      if (snapshot_version >= 7) w->Bool(k.verified);  // before version 7 none was verified
      if (snapshot_version >= 10) {                    // before version 10 none was measured
        w->F64(k.conflict);
        w->I64(k.conflict_points);
      }
    }
  }
  PutMap(w, s.qualified_since);
  w->I64(s.now_utime);
  PutMap(w, s.near_quiet_until);
  w->Size(s.near_index.size());
  for (const auto& [trajectory, index] : s.near_index) {
    Put(w, trajectory);
    w->Size(index.entries.size());
    for (const auto& [item, position] : index.entries) {
      w->I32(item);
      w->F64(position.x());
      w->F64(position.y());
    }
    w->Size(index.indexed);
    w->I64(index.refreshed_utime);
    w->I64(index.merges);
  }
  Put(w, s.stats);
  if (snapshot_version < 5) return;
  w->Size(s.near_held.size());
  for (const auto& [pair, held] : s.near_held) {
    Put(w, pair);
    w->Size(held.size());
    for (const ScanEncounterCandidateState& c : held) PutCandidate(w, c);
  }
  if (snapshot_version < 6) return;
  w->Bool(s.near_joined_known);
  w->Size(s.near_joined.size());
  for (const auto& pair : s.near_joined) Put(w, pair);
  PutBudget(w, snapshot_version, s.near_budget);
  if (snapshot_version >= 12) w->I64(s.near_folded);
}

void GetScanEncounterState(ByteReader* r, uint32_t snapshot_version, ScanEncounterState* s) {
  // Before version 6 no pair was caught up: the pairs in one frame then are taken as caught
  // up (the source finds them at its next look).
  s->near_joined.clear();
  s->near_joined_known = false;
  s->matches.resize(r->Count(8));
  for (ScanEncounterState::Match& m : s->matches) {
    m.due_utime = r->I64();
    Get(r, &m.key);
    Get(r, &m.center);
    m.global = r->Bool();
    m.wide = snapshot_version >= 5 && r->Bool();  // before version 5 none was wide
    m.key_utime = r->I64();
    GetResult(r, &m.result);
  }
  GetKeys(r, &s->waiting);
  s->submaps.clear();
  for (size_t i = 0, n = r->Count(); i < n && !r->failed(); ++i) {
    TrajectoryId trajectory(0);
    Get(r, &trajectory);
    auto& submaps = s->submaps[trajectory];
    submaps.resize(r->Count(12));
    for (auto& [center, drawing] : submaps) {
      Get(r, &center);
      Get(r, &drawing.center);
      drawing.T_center_keyframes.resize(r->Count(sizeof(int32_t) + 3 * sizeof(double)));
      for (auto& [index, pose] : drawing.T_center_keyframes) {
        index = r->I32();
        pose = r->Pose();
      }
      drawing.num_points = static_cast<size_t>(r->Raw<uint64_t>());
    }
  }
  GetMap(r, &s->global_cursor);
  GlobalSearchQueue::State& q = s->global_queue;
  GetTokens(r, &q.tokens, &q.last_utime);
  q.waiting.clear();
  for (size_t i = 0, n = r->Count(); i < n && !r->failed(); ++i) {
    TrajectoryId trajectory(0);
    Get(r, &trajectory);
    PoseKey key;
    Get(r, &key);
    q.waiting.emplace(trajectory, key);
  }
  GetMap(r, &q.searched);
  GetMap(r, &q.pair_searched);
  q.searches = r->I64();
  q.dropped = r->I64();
  s->kept.clear();
  for (size_t i = 0, n = r->Count(); i < n && !r->failed(); ++i) {
    Pair pair{TrajectoryId(0), TrajectoryId(0)};
    Get(r, &pair);
    auto& kept = s->kept[pair];
    kept.resize(r->Count(8));
    for (ScanEncounterState::Kept& k : kept) {
      GetCandidate(r, &k.candidate);
      k.support = r->I32();
      k.localised = r->Bool();
      k.verified = snapshot_version >= 7 && r->Bool();  // before version 7 none was verified
      if (snapshot_version >= 10) {                     // before version 10 none was measured
        k.conflict = r->F64();
        k.conflict_points = r->I64();
      }
    }
  }
  GetMap(r, &s->qualified_since);
  s->now_utime = r->I64();
  GetMap(r, &s->near_quiet_until);
  s->near_index.clear();
  for (size_t i = 0, n = r->Count(); i < n && !r->failed(); ++i) {
    TrajectoryId trajectory(0);
    Get(r, &trajectory);
    ScanEncounterState::NearIndex& index = s->near_index[trajectory];
    index.entries.resize(r->Count(sizeof(int32_t) + 2 * sizeof(double)));
    for (auto& [item, position] : index.entries) {
      item = r->I32();
      const double x = r->F64();
      position = Eigen::Vector2d(x, r->F64());
    }
    index.indexed = static_cast<size_t>(r->Raw<uint64_t>());
    index.refreshed_utime = r->I64();
    index.merges = r->I64();
  }
  Get(r, &s->stats);
  s->near_held.clear();
  s->near_budget.reset();
  s->near_folded = 0;
  if (snapshot_version < 5) return;
  for (size_t i = 0, n = r->Count(); i < n && !r->failed(); ++i) {
    Pair pair{TrajectoryId(0), TrajectoryId(0)};
    Get(r, &pair);
    auto& held = s->near_held[pair];
    held.resize(r->Count(8));
    for (ScanEncounterCandidateState& c : held) GetCandidate(r, &c);
  }
  if (snapshot_version < 6) return;
  s->near_joined_known = r->Bool();
  for (size_t i = 0, n = r->Count(); i < n && !r->failed(); ++i) {
    Pair pair{TrajectoryId(0), TrajectoryId(0)};
    Get(r, &pair);
    s->near_joined.insert(pair);
  }
  GetBudget(r, snapshot_version, &s->near_budget);
  if (snapshot_version >= 12) s->near_folded = r->I64();
}

namespace {

// Every fold counter, in declaration order: a new field must be added here (the size check).
static_assert(sizeof(KeyframeFoldStats) == 8 * 8, "KeyframeFoldStats changed: update the codec");
template <typename Stats, typename OnCount>
void ForEachFoldCount(Stats& s, OnCount on_count) {
  for (auto* v : {&s.examined, &s.no_candidate, &s.unsolved, &s.no_scan, &s.weak_match,
                  &s.gate_rejected, &s.degenerate, &s.folded}) {
    on_count(v);
  }
}

}  // namespace

void PutKeyframeFolderState(ByteWriter* w, const KeyframeFolderState& s) {
  w->Size(s.nodes.size());
  for (const KeyframeFolderState::Node& n : s.nodes) {
    Put(w, n.node);
    Put(w, n.keyframe);
  }
  w->Size(s.index.size());
  for (const auto& [frame, entries] : s.index) {
    w->Bool(frame.first);
    Put(w, frame.second);
    w->Size(entries.size());
    for (const auto& [item, position] : entries) {
      w->I32(item);
      w->F64(position.x());
      w->F64(position.y());
    }
  }
  w->I64(s.indexed_at_update);
  KeyframeFoldStats stats = s.stats;
  ForEachFoldCount(stats, [w](int64_t* v) { w->I64(*v); });
}

void GetKeyframeFolderState(ByteReader* r, KeyframeFolderState* s) {
  s->nodes.resize(r->Count(2 * (sizeof(int64_t) + sizeof(int32_t))));
  for (KeyframeFolderState::Node& n : s->nodes) {
    Get(r, &n.node);
    Get(r, &n.keyframe);
  }
  s->index.clear();
  for (size_t i = 0, n = r->Count(1 + sizeof(int64_t) + 8); i < n && !r->failed(); ++i) {
    TrajectoryFrame frame{false, TrajectoryId(0)};
    frame.first = r->Bool();
    Get(r, &frame.second);
    std::vector<std::pair<int32_t, Eigen::Vector2d>> entries(
        r->Count(sizeof(int32_t) + 2 * sizeof(double)));
    for (auto& [item, position] : entries) {
      item = r->I32();
      const double x = r->F64();
      position = Eigen::Vector2d(x, r->F64());
    }
    s->index.emplace_back(frame, std::move(entries));
  }
  s->indexed_at_update = r->I64();
  s->stats = KeyframeFoldStats{};
  ForEachFoldCount(s->stats, [r](int64_t* v) { *v = r->I64(); });
}

}  // namespace anchormap
