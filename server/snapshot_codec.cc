#include "server/snapshot_codec.h"

#include <cstring>
#include <deque>
#include <map>
#include <optional>
#include <tuple>
#include <type_traits>
#include <utility>

#include "server/byte_codec.h"
#include "server/smoother_state_codec.h"
#include "server/source_state_codec.h"

namespace anchormap {
namespace {

constexpr char kMagic[8] = {'A', 'M', 'S', 'N', 'A', 'P', 'S', 'H'};
constexpr size_t kHeaderSize = 8 + 4 + 8;  // magic, version, payload size
constexpr size_t kTrailerSize = 8;         // checksum

uint64_t Fnv1a64(const uint8_t* data, size_t size) {
  uint64_t hash = 0xcbf29ce484222325ULL;
  for (size_t i = 0; i < size; ++i) {
    hash ^= data[i];
    hash *= 0x100000001b3ULL;
  }
  return hash;
}

using Writer = ByteWriter;
using Reader = ByteReader;

// --- The value types, each written and read in one place ---

void Put(Writer* w, const LaserScan& s) {
  w->I64(s.utime);
  w->Raw(s.rad0);
  w->Raw(s.radstep);
  w->Raw(s.max_range);
  w->Size(s.ranges.size());
  for (float r : s.ranges) w->Raw(r);
  w->Pose(s.T_body_sensor);
}
void Get(Reader* r, LaserScan* s) {
  s->utime = r->I64();
  s->rad0 = r->Raw<float>();
  s->radstep = r->Raw<float>();
  s->max_range = r->Raw<float>();
  s->ranges.resize(r->Count(sizeof(float)));
  for (float& range : s->ranges) range = r->Raw<float>();
  s->T_body_sensor = r->Pose();
}

// Version 3 adds the count of relayed encounters a keyframe carries.
constexpr uint32_t kRelayCountsVersion = 3;
// Version 4 adds the solve period's state.
constexpr uint32_t kSolvePeriodVersion = 4;
// Version 12 adds the reduced graph: alias graph edits and the folder's state.
constexpr uint32_t kReducedGraphVersion = 12;

void Put(Writer* w, const Keyframe& k, uint32_t version) {
  w->String(k.robot);
  w->I64(k.trajectory_id);
  w->I32(k.seq);
  if (version >= kRelayCountsVersion) w->I32(k.encounters_relayed);
  w->I64(k.utime);
  w->Pose(k.T_local_pose);
  w->Pose(k.T_previous_this);
  w->Matrix(k.T_previous_this_covariance);
  Put(w, k.scan);
}
void Get(Reader* r, Keyframe* k, uint32_t version) {
  k->robot = r->String();
  k->trajectory_id = r->I64();
  k->seq = r->I32();
  k->encounters_relayed = version >= kRelayCountsVersion ? r->I32() : 0;
  k->utime = r->I64();
  k->T_local_pose = r->Pose();
  k->T_previous_this = r->Pose();
  k->T_previous_this_covariance = r->Matrix();
  Get(r, &k->scan);
}

void Put(Writer* w, const Encounter& e) {
  w->I64(e.utime);
  w->String(e.observer);
  w->I64(e.observer_trajectory_id);
  w->String(e.observed);
  w->Pose(e.T_observer_observed);
  w->Matrix(e.covariance);
  w->I32(e.seq);
}
void Get(Reader* r, Encounter* e) {
  e->utime = r->I64();
  e->observer = r->String();
  e->observer_trajectory_id = r->I64();
  e->observed = r->String();
  e->T_observer_observed = r->Pose();
  e->covariance = r->Matrix();
  e->seq = r->I32();
}

void Put(Writer* w, const TrajectoryName& n) {
  w->String(n.robot);
  w->I64(n.id);
}
void Get(Reader* r, TrajectoryName* n) {
  n->robot = r->String();
  n->id = r->I64();
}

void Put(Writer* w, const PoseKey& k) {
  w->I64(k.trajectory.value());
  w->I32(k.index);
}
void Get(Reader* r, PoseKey* k) {
  k->trajectory = TrajectoryId(r->I64());
  k->index = r->I32();
}

void Put(Writer* w, const std::string& s) { w->String(s); }
void Get(Reader* r, std::string* s) { *s = r->String(); }
void Put(Writer* w, int64_t v) { w->I64(v); }
void Get(Reader* r, int64_t* v) { *v = r->I64(); }
void Put(Writer* w, int32_t v) { w->I32(v); }
void Get(Reader* r, int32_t* v) { *v = r->I32(); }
void Put(Writer* w, size_t v) { w->Size(v); }
void Get(Reader* r, size_t* v) { *v = static_cast<size_t>(r->Raw<uint64_t>()); }
void Put(Writer* w, const Pose2& p) { w->Pose(p); }
void Get(Reader* r, Pose2* p) { *p = r->Pose(); }

template <typename A, typename B>
void Put(Writer* w, const std::pair<A, B>& p) {
  Put(w, p.first);
  Put(w, p.second);
}
template <typename A, typename B>
void Get(Reader* r, std::pair<A, B>* p) {
  Get(r, &p->first);
  Get(r, &p->second);
}

// Containers: a count, then the items.
template <typename Container>
void PutAll(Writer* w, const Container& items) {
  w->Size(items.size());
  for (const auto& item : items) Put(w, item);
}
template <typename T, typename Sequence>
void GetSequence(Reader* r, Sequence* out) {
  out->clear();
  const size_t n = r->Count();
  for (size_t i = 0; i < n && !r->failed(); ++i) {
    T item{};
    Get(r, &item);
    out->push_back(std::move(item));
  }
}
template <typename K, typename V, typename Map>
void GetMap(Reader* r, Map* out) {
  out->clear();
  const size_t n = r->Count();
  for (size_t i = 0; i < n && !r->failed(); ++i) {
    K key{};
    Get(r, &key);
    V value{};
    Get(r, &value);
    out->emplace(std::move(key), std::move(value));
  }
}
template <typename T, typename Set>
void GetSet(Reader* r, Set* out) {
  out->clear();
  const size_t n = r->Count();
  for (size_t i = 0; i < n && !r->failed(); ++i) {
    T item{};
    Get(r, &item);
    out->insert(std::move(item));
  }
}

void Put(Writer* w, const JournalPosition& p) {
  w->I64(p.events);
  w->I64(p.last_utime);
  w->String(p.last_channel);
}
void Get(Reader* r, JournalPosition* p) {
  p->events = r->I64();
  p->last_utime = r->I64();
  p->last_channel = r->String();
}

Status Corrupt(const std::string& why) {
  return Status::Error(ErrorCode::kDecodeFailed, "snapshot refused: " + why);
}

// An opened envelope: the payload's bounds and the format version.
struct Payload {
  const uint8_t* data = nullptr;
  size_t size = 0;
  uint32_t version = 0;
};

// Opens the envelope: the payload, or why not.
Result<Payload> OpenEnvelope(const uint8_t* data, size_t size) {
  if (size < kHeaderSize + kTrailerSize)
    return Corrupt("truncated (" + std::to_string(size) + " bytes)");
  if (std::memcmp(data, kMagic, sizeof(kMagic)) != 0) return Corrupt("not a snapshot (magic)");
  Reader header(data + sizeof(kMagic), kHeaderSize - sizeof(kMagic));
  const uint32_t version = header.Raw<uint32_t>();
  const uint64_t payload_size = header.Raw<uint64_t>();
  if (version < kOldestSnapshotVersion || version > kSnapshotVersion) {
    return Corrupt("version " + std::to_string(version) + ", this server reads " +
                   std::to_string(kOldestSnapshotVersion) + " to " +
                   std::to_string(kSnapshotVersion));
  }
  if (payload_size != size - kHeaderSize - kTrailerSize) {
    return Corrupt("truncated or padded (payload " + std::to_string(payload_size) +
                   " bytes, file " + std::to_string(size) + ")");
  }
  Reader trailer(data + size - kTrailerSize, kTrailerSize);
  if (trailer.Raw<uint64_t>() != Fnv1a64(data, size - kTrailerSize)) return Corrupt("checksum");
  return Payload{data + kHeaderSize, static_cast<size_t>(payload_size), version};
}

// The scan-matching sources in a version-2 snapshot, in the server's order of sources.
enum class SourceKind : uint8_t { kLoopClosures = 1, kScanEncounters = 2 };

}  // namespace

// --- The classes' state; the order of sections is the format ---

// The classes' friend (they declare it): their private state is read and written only here.
struct SnapshotAccess {
  static Result<std::vector<uint8_t>> Encode(const MappingServer& s, const SnapshotNodeState& node,
                                             uint32_t version);
  static Status Decode(const uint8_t* data, size_t size, MappingServer* s, SnapshotNodeState* node);
  static void PutTable(Writer* w, const TrajectoryTable& t, uint32_t version);
  static void GetTable(Reader* r, TrajectoryTable* t, uint32_t version);
  static void PutOrder(Writer* w, const CanonicalInputOrder& o, uint32_t version);
  static void GetOrder(Reader* r, CanonicalInputOrder* o, uint32_t version);
};

Result<std::vector<uint8_t>> SnapshotCodec::Encode(const MappingServer& server,
                                                   const SnapshotNodeState& node) {
  return SnapshotAccess::Encode(server, node, kSnapshotVersion);
}

Result<std::vector<uint8_t>> SnapshotCodec::EncodeVersion(const MappingServer& server,
                                                          const SnapshotNodeState& node,
                                                          uint32_t version) {
  if (version < 2 || version > kSnapshotVersion) {
    return Status::Error(ErrorCode::kInvalidArgument,
                         "snapshot version " + std::to_string(version) + " is not written");
  }
  return SnapshotAccess::Encode(server, node, version);
}

Status SnapshotCodec::Decode(const uint8_t* data, size_t size, MappingServer* server,
                             SnapshotNodeState* node) {
  return SnapshotAccess::Decode(data, size, server, node);
}

Result<std::vector<uint8_t>> SnapshotAccess::Encode(const MappingServer& s,
                                                    const SnapshotNodeState& node,
                                                    uint32_t version) {
  if (!s.CanSnapshot()) {
    return Status::Error(ErrorCode::kInvalidArgument,
                         "snapshots need the server's own sources (direct encounters, loop "
                         "closures, scan encounters; no added one) and no deferral in progress");
  }
  if (s.folder_ && version < kReducedGraphVersion) {
    return Status::Error(ErrorCode::kInvalidArgument,
                         "snapshot version " + std::to_string(version) +
                             " cannot hold the reduced graph (version " +
                             std::to_string(kReducedGraphVersion) + " on)");
  }
  Writer w;
  w.bytes().assign(kMagic, kMagic + sizeof(kMagic));
  w.Raw<uint32_t>(version);
  w.Raw<uint64_t>(0);  // payload size, filled in below
  // The node.
  Put(&w, node.position);
  PutAll(&w, node.robots);
  PutAll(&w, node.trajectories);
  // MappingServer's scalars and counters.
  const MappingServerStats& st = s.stats_;
  for (int64_t v : {st.keyframes_received, st.encounters_received, st.encounters_added, st.updates,
                    st.deferred_updates, st.solver_problems}) {
    w.I64(v);
  }
  w.Size(st.added_by_kind.size());
  for (int64_t v : st.added_by_kind) w.I64(v);
  for (int64_t v : {s.data_utime_, s.released_utime_, s.clock_utime_, s.resend_requests_,
                    s.encounters_given_up_}) {
    w.I64(v);
  }
  if (version >= kSolvePeriodVersion) {
    w.I64(s.last_solve_utime_);
    w.Bool(s.solve_pending_);
  }
  w.Size(static_cast<size_t>(ErrorCode::kNumCodes));
  for (int i = 0; i < static_cast<int>(ErrorCode::kNumCodes); ++i) {
    w.I64(s.rejects_.count(static_cast<ErrorCode>(i)));
  }
  // Delivery: the receipt table, the keyframes it holds the scans of, the relayed
  // encounters' windows and gap clocks, the resend rate limit.
  SnapshotAccess::PutTable(&w, s.receipt_, version);
  w.Size(s.arrived_.size());
  for (const auto& [key, keyframe] : s.arrived_) {
    Put(&w, keyframe, version);  // the key follows from it
  }
  w.Size(s.encounter_seqs_.size());
  for (const auto& [name, window] : s.encounter_seqs_) {
    Put(&w, name);
    w.I32(window.next_);
    PutAll(&w, window.above_);
    if (version >= kRelayCountsVersion) w.I32(window.expected_);
  }
  PutAll(&w, s.encounter_gap_since_);
  PutAll(&w, s.resend_.last_request_utime_);
  // The order stage, the graph's table, the links.
  SnapshotAccess::PutOrder(&w, s.order_, version);
  SnapshotAccess::PutTable(&w, s.table_, version);
  w.Size(s.links_.size());
  for (const EncounterLink& l : s.links_) {
    w.String(l.robot_a);
    w.I64(l.trajectory_a);
    w.I32(l.index_a);
    w.String(l.robot_b);
    w.I64(l.trajectory_b);
    w.I32(l.index_b);
    w.U8(static_cast<uint8_t>(l.kind));
  }
  // The smoother's graph: its edits in order (a pose with the initial guess it was given; the
  // reduced graph's aliases, version 12 on).
  w.Size(s.graph_edits_.size());
  for (const GraphEdit& e : s.graph_edits_) {
    w.U8(static_cast<uint8_t>(e.kind));
    Put(&w, e.a);
    Put(&w, e.b);
    w.Pose(e.measured);
    if (e.kind != GraphEdit::Kind::kPose) w.Matrix(e.covariance);
  }
  // The direct-encounter source.
  const auto& direct = dynamic_cast<const DirectEncounters&>(*s.sources_.front());
  PutAll(&w, direct.pending_);
  w.I64(direct.now_utime_);
  // Version 2: the smoother's incremental state (its graph follows from the edits above),
  // the match pool's numbering, the scan-matching sources (their matches in flight waited
  // for: server/loop_closure_state.h).
  PutSmootherState(&w, version, s.smoother_.ExportState());
  w.I64(s.pool_->next_ordinal());
  w.Size(s.sources_.size() - 1);
  for (size_t i = 1; i < s.sources_.size(); ++i) {
    if (const auto* loop = dynamic_cast<const LoopClosures*>(s.sources_[i].get())) {
      w.U8(static_cast<uint8_t>(SourceKind::kLoopClosures));
      PutLoopClosureState(&w, version, loop->ExportState());
    } else {
      const auto& scan = dynamic_cast<const ScanEncounters&>(*s.sources_[i]);
      w.U8(static_cast<uint8_t>(SourceKind::kScanEncounters));
      PutScanEncounterState(&w, version, scan.ExportState());
    }
  }
  // Version 12: the reduced graph's folder, if the server has one (its aliases are edits).
  if (version >= kReducedGraphVersion) {
    w.Bool(s.folder_ != nullptr);
    if (s.folder_) PutKeyframeFolderState(&w, s.folder_->ExportState());
  }

  std::vector<uint8_t>& bytes = w.bytes();
  const uint64_t payload_size = bytes.size() - kHeaderSize;
  std::memcpy(bytes.data() + sizeof(kMagic) + 4, &payload_size, sizeof(payload_size));
  const uint64_t checksum = Fnv1a64(bytes.data(), bytes.size());
  w.Raw(checksum);
  return std::move(bytes);
}

Result<JournalPosition> SnapshotCodec::ReadPosition(const uint8_t* data, size_t size) {
  const auto payload = OpenEnvelope(data, size);
  if (!payload.ok()) return payload.status();
  Reader r(payload->data, payload->size);
  JournalPosition position;
  Get(&r, &position);
  if (r.failed() || position.events < 0) return Corrupt("bad journal position");
  return position;
}

Status SnapshotAccess::Decode(const uint8_t* data, size_t size, MappingServer* s,
                              SnapshotNodeState* node) {
  const auto payload = OpenEnvelope(data, size);
  if (!payload.ok()) return payload.status();
  const bool version1 = payload->version == 1;
  if (!s->CanSnapshot() || (version1 && s->sources_.size() != 1)) {
    return Status::Error(ErrorCode::kInvalidArgument,
                         version1 ? "this server has a scan-matching source: a version-1 "
                                    "snapshot holds none"
                                  : "this server has a source a snapshot cannot hold");
  }
  // A version-1 snapshot is restored by deferred updates, which the fold does not allow.
  if (version1 && s->folder_) {
    return Status::Error(ErrorCode::kInvalidArgument,
                         "this server folds keyframes (reduced graph): a version-1 snapshot "
                         "restores by deferring updates, which the fold cannot");
  }
  Reader r(payload->data, payload->size);
  Get(&r, &node->position);
  GetSet<std::string>(&r, &node->robots);
  GetSet<TrajectoryName>(&r, &node->trajectories);
  MappingServerStats& st = s->stats_;
  for (int64_t* v : {&st.keyframes_received, &st.encounters_received, &st.encounters_added,
                     &st.updates, &st.deferred_updates, &st.solver_problems}) {
    *v = r.I64();
  }
  if (r.Count() != st.added_by_kind.size()) return Corrupt("constraint kinds");
  for (int64_t& v : st.added_by_kind) v = r.I64();
  for (int64_t* v : {&s->data_utime_, &s->released_utime_, &s->clock_utime_, &s->resend_requests_,
                     &s->encounters_given_up_}) {
    *v = r.I64();
  }
  // Before version 4 every input was solved at once.
  s->last_solve_utime_ = s->released_utime_;
  s->solve_pending_ = false;
  if (payload->version >= kSolvePeriodVersion) {
    s->last_solve_utime_ = r.I64();
    s->solve_pending_ = r.Bool();
  }
  if (r.Count() != static_cast<size_t>(ErrorCode::kNumCodes)) return Corrupt("refusal reasons");
  for (int i = 0; i < static_cast<int>(ErrorCode::kNumCodes); ++i) {
    s->rejects_.Restore(static_cast<ErrorCode>(i), r.I64());
  }
  const uint32_t version = payload->version;
  SnapshotAccess::GetTable(&r, &s->receipt_, version);
  s->arrived_.clear();
  for (size_t i = 0, n = r.Count(); i < n && !r.failed(); ++i) {
    Keyframe k;
    Get(&r, &k, version);
    const auto key = std::make_tuple(k.robot, k.trajectory_id, k.seq, k.utime);
    s->arrived_.emplace(key, std::move(k));
  }
  s->encounter_seqs_.clear();
  for (size_t i = 0, n = r.Count(); i < n && !r.failed(); ++i) {
    TrajectoryName name;
    Get(&r, &name);
    SeqWindow& window = s->encounter_seqs_[name];
    window.next_ = r.I32();
    GetSet<int32_t>(&r, &window.above_);
    window.expected_ = version >= kRelayCountsVersion ? r.I32() : 0;
  }
  GetMap<TrajectoryName, int64_t>(&r, &s->encounter_gap_since_);
  GetMap<TrajectoryName, int64_t>(&r, &s->resend_.last_request_utime_);
  SnapshotAccess::GetOrder(&r, &s->order_, version);
  SnapshotAccess::GetTable(&r, &s->table_, version);
  s->links_.clear();
  for (size_t i = 0, n = r.Count(); i < n && !r.failed(); ++i) {
    EncounterLink l;
    l.robot_a = r.String();
    l.trajectory_a = r.I64();
    l.index_a = r.I32();
    l.robot_b = r.String();
    l.trajectory_b = r.I64();
    l.index_b = r.I32();
    const uint8_t kind = r.U8();
    if (kind >= kNumConstraintKinds) return Corrupt("constraint kind");
    l.kind = static_cast<ConstraintKind>(kind);
    s->links_.push_back(std::move(l));
  }
  // The smoother: the same calls in the same order (the same variables, factors, gauge
  // priors and anchor groups), each pose from the initial guess the live run gave it. Version
  // 2 then imports the incremental state (below); version 1 held none: one batch step
  // (EndDeferredUpdates) solves. (Starting from the snapshot's estimate instead, the final
  // maps differed by up to 2.6e-9 m in the codec test; from the live guesses, by 1e-14.)
  s->graph_edits_.clear();
  s->ties_.Clear();
  s->smoother_ = Smoother(s->options_.smoother);
  for (size_t i = 0, n = r.Count(); i < n && !r.failed(); ++i) {
    GraphEdit e;
    const uint8_t kind = r.U8();
    const GraphEdit::Kind last = payload->version >= kReducedGraphVersion
                                     ? GraphEdit::Kind::kAlias
                                     : GraphEdit::Kind::kEncounter;
    if (kind > static_cast<uint8_t>(last)) return Corrupt("graph edit");
    e.kind = static_cast<GraphEdit::Kind>(kind);
    Get(&r, &e.a);
    Get(&r, &e.b);
    e.measured = r.Pose();
    if (e.kind != GraphEdit::Kind::kPose) e.covariance = r.Matrix();
    if (r.failed()) break;
    Status added;
    switch (e.kind) {
      case GraphEdit::Kind::kPose:
        added = s->smoother_.AddPose(e.a, e.measured);
        break;
      case GraphEdit::Kind::kBetween:
        added = s->smoother_.AddBetween(e.a, e.b, e.measured, e.covariance);
        break;
      case GraphEdit::Kind::kEncounter:
        added = s->smoother_.AddEncounter(e.a, e.b, e.measured, e.covariance);
        if (added.ok()) s->ties_.Add(e.a, e.b);
        break;
      case GraphEdit::Kind::kAlias:
        added = s->smoother_.AddAlias(e.a, e.b, e.measured, e.covariance);
        break;
    }
    if (!added.ok()) return Corrupt("graph edit " + std::to_string(i) + ": " + added.message());
    s->graph_edits_.push_back(e);
  }
  auto& direct = dynamic_cast<DirectEncounters&>(*s->sources_.front());
  GetSequence<Encounter>(&r, &direct.pending_);
  direct.now_utime_ = r.I64();
  if (!version1) {
    SmootherState smoother;
    GetSmootherState(&r, payload->version, &smoother);
    const int64_t next_ordinal = r.I64();
    const size_t sources = r.Count();
    if (r.failed()) return Corrupt("payload ends early");
    if (sources != s->sources_.size() - 1) return Corrupt("another set of sources");
    if (Status imported = s->smoother_.ImportState(std::move(smoother)); !imported.ok()) {
      return Corrupt(imported.message());
    }
    s->pool_->ContinueAt(next_ordinal);
    for (size_t i = 1; i < s->sources_.size() && !r.failed(); ++i) {
      const auto kind = static_cast<SourceKind>(r.U8());
      auto* loop = dynamic_cast<LoopClosures*>(s->sources_[i].get());
      auto* scan = dynamic_cast<ScanEncounters*>(s->sources_[i].get());
      if (kind == SourceKind::kLoopClosures && loop != nullptr) {
        LoopClosureState state;
        GetLoopClosureState(&r, payload->version, &state);
        loop->ImportState(state);
      } else if (kind == SourceKind::kScanEncounters && scan != nullptr) {
        ScanEncounterState state;
        GetScanEncounterState(&r, payload->version, &state);
        scan->ImportState(state);
      } else {
        return Corrupt("source " + std::to_string(i) + " is not the server's");
      }
    }
  }
  // The reduced graph's folder. A snapshot without one (older, or of a server without the
  // option) into a server with it: every pose is a node verified by its own keyframe's scan,
  // as if the option had been on with that graph (no alias, no borrowed node: the edits hold
  // none), the index built at the first fold. The other way round is refused: the aliases
  // would stay, but no keyframe would fold or borrow a node after them.
  if (s->folder_) s->folder_ = std::make_unique<KeyframeFolder>(s->options_.reduced_graph);
  const bool has_folder = payload->version >= kReducedGraphVersion && r.Bool();
  if (has_folder && !s->folder_) {
    return Corrupt("the snapshot's server folds keyframes (reduced graph), this one does not");
  }
  if (has_folder) {
    KeyframeFolderState folder;
    GetKeyframeFolderState(&r, &folder);
    s->folder_->ImportState(folder);
  } else if (s->folder_) {
    for (const GraphEdit& e : s->graph_edits_) {
      if (e.kind == GraphEdit::Kind::kPose) s->folder_->AddNode(e.a, e.a, s->smoother_);
    }
  }
  if (r.failed()) return Corrupt("payload ends early");
  if (!r.at_end()) return Corrupt("bytes after the last section");
  // Version 2: the exact state, solved; the journal's tail is replayed as it ran live.
  if (!version1) return Status::Ok();
  // Version 1: unsolved, deferring: the journal's tail is replayed deferred and one batch
  // step then solves everything (EndDeferredUpdates), rather than one step here and one after.
  s->deferring_ = true;
  s->unsolved_ = s->smoother_.stats().variables > 0;
  s->variables_at_deferred_batch_ = s->smoother_.stats().variables;
  return Status::Ok();
}

void SnapshotAccess::PutTable(Writer* w, const TrajectoryTable& t, uint32_t version) {
  w->Size(t.records_.size());
  for (const TrajectoryRecord& rec : t.records_) {
    w->String(rec.robot);
    w->I64(rec.agent_trajectory_id);
    w->I64(rec.solver_id.value());
    PutAll(w, rec.seqs);
    PutAll(w, rec.utimes);
    PutAll(w, rec.odometry_poses);
    w->Size(rec.scans.size());
    for (const LaserScan& scan : rec.scans) Put(w, scan);
  }
  w->Size(t.pending_.size());
  for (const TrajectoryTable::Pending& p : t.pending_) {
    w->I32(p.next_seq);
    w->Bool(p.started);
    w->I64(p.gap_since);
    if (version >= kRelayCountsVersion) w->I32(p.admitted_encounters_relayed);
    w->Size(p.held.size());
    for (const auto& [seq, keyframe] : p.held) Put(w, keyframe, version);  // seq == keyframe.seq
  }
  PutAll(w, t.index_);
  w->I64(t.num_keyframes_);
  w->I64(t.num_bridged_gaps_);
  w->I64(t.num_reused_ids_);
}

void SnapshotAccess::GetTable(Reader* r, TrajectoryTable* t, uint32_t version) {
  t->records_.clear();
  for (size_t i = 0, n = r->Count(); i < n && !r->failed(); ++i) {
    TrajectoryRecord rec;
    rec.robot = r->String();
    rec.agent_trajectory_id = r->I64();
    rec.solver_id = TrajectoryId(r->I64());
    GetSequence<int32_t>(r, &rec.seqs);
    GetSequence<int64_t>(r, &rec.utimes);
    GetSequence<Pose2>(r, &rec.odometry_poses);
    rec.scans.resize(r->Count());
    for (LaserScan& scan : rec.scans) Get(r, &scan);
    t->records_.push_back(std::move(rec));
  }
  t->pending_.clear();
  for (size_t i = 0, n = r->Count(); i < n && !r->failed(); ++i) {
    TrajectoryTable::Pending p;
    p.next_seq = r->I32();
    p.started = r->Bool();
    p.gap_since = r->I64();
    p.admitted_encounters_relayed = version >= kRelayCountsVersion ? r->I32() : 0;
    for (size_t j = 0, m = r->Count(); j < m && !r->failed(); ++j) {
      Keyframe k;
      Get(r, &k, version);
      const int32_t seq = k.seq;
      p.held.emplace(seq, std::move(k));
    }
    t->pending_.push_back(std::move(p));
  }
  GetMap<TrajectoryName, size_t>(r, &t->index_);
  t->num_keyframes_ = r->I64();
  t->num_bridged_gaps_ = r->I64();
  t->num_reused_ids_ = r->I64();
}

namespace {

using OrderKey = std::tuple<int64_t, int, std::string, int64_t, int32_t, std::string, int64_t>;

void PutKey(Writer* w, const OrderKey& k) {
  w->I64(std::get<0>(k));
  w->I32(std::get<1>(k));
  w->String(std::get<2>(k));
  w->I64(std::get<3>(k));
  w->I32(std::get<4>(k));
  w->String(std::get<5>(k));
  w->I64(std::get<6>(k));
}
OrderKey GetKey(Reader* r) {
  OrderKey k;
  std::get<0>(k) = r->I64();
  std::get<1>(k) = r->I32();
  std::get<2>(k) = r->String();
  std::get<3>(k) = r->I64();
  std::get<4>(k) = r->I32();
  std::get<5>(k) = r->String();
  std::get<6>(k) = r->I64();
  return k;
}

template <typename Entry>
void PutEntry(Writer* w, const Entry& e, uint32_t version) {
  PutKey(w, e.key);
  w->I64(e.arrival_clock);
  w->Bool(e.input.is_keyframe);
  if (e.input.is_keyframe) {
    Put(w, e.input.keyframe, version);
  } else {
    Put(w, e.input.encounter);
  }
}
template <typename Entry>
Entry GetEntry(Reader* r, uint32_t version) {
  Entry e;
  e.key = GetKey(r);
  e.arrival_clock = r->I64();
  e.input.is_keyframe = r->Bool();
  if (e.input.is_keyframe) {
    Get(r, &e.input.keyframe, version);
  } else {
    Get(r, &e.input.encounter);
  }
  return e;
}

}  // namespace

void SnapshotAccess::PutOrder(Writer* w, const CanonicalInputOrder& o, uint32_t version) {
  static_assert(std::is_same<CanonicalInputOrder::Key, OrderKey>::value, "the order key changed");
  w->Size(o.streams_.size());
  for (const auto& [id, stream] : o.streams_) {
    w->I64(id.value());
    w->Size(stream.queue.size());
    for (const auto& entry : stream.queue) PutEntry(w, entry, version);
    w->Bool(stream.started);
    w->I64(stream.watermark);
    w->I64(stream.last_heard);
    w->Bool(stream.silent);
  }
  w->Size(o.encounters_.size());
  for (const auto& [key, entry] : o.encounters_) PutEntry(w, entry, version);  // key == entry.key
  w->Size(o.encounter_streams_.size());
  for (const auto& [name, stream] : o.encounter_streams_) {
    w->String(name.first);
    w->I64(name.second);
    w->I32(stream.next_seq);
    w->I64(stream.last_utime);
    PutAll(w, stream.above);
    w->I64(stream.gap_since);
    if (version >= kRelayCountsVersion) w->I32(stream.expected);
  }
  w->I64(o.arrivals_);
  w->Bool(o.last_released_.has_value());
  if (o.last_released_) PutKey(w, *o.last_released_);
  for (int64_t v : {o.stats_.released, o.stats_.late, o.stats_.silences, o.stats_.peak_held}) {
    w->I64(v);
  }
}

void SnapshotAccess::GetOrder(Reader* r, CanonicalInputOrder* o, uint32_t version) {
  using Entry = CanonicalInputOrder::Entry;
  o->streams_.clear();
  for (size_t i = 0, n = r->Count(); i < n && !r->failed(); ++i) {
    CanonicalInputOrder::Stream& stream = o->streams_[TrajectoryId(r->I64())];
    for (size_t j = 0, m = r->Count(); j < m && !r->failed(); ++j) {
      stream.queue.push_back(GetEntry<Entry>(r, version));
    }
    stream.started = r->Bool();
    stream.watermark = r->I64();
    stream.last_heard = r->I64();
    stream.silent = r->Bool();
  }
  o->encounters_.clear();
  for (size_t i = 0, n = r->Count(); i < n && !r->failed(); ++i) {
    Entry entry = GetEntry<Entry>(r, version);
    const OrderKey key = entry.key;
    o->encounters_.emplace(key, std::move(entry));
  }
  o->encounter_streams_.clear();
  for (size_t i = 0, n = r->Count(); i < n && !r->failed(); ++i) {
    std::pair<std::string, int64_t> name;
    name.first = r->String();
    name.second = r->I64();
    CanonicalInputOrder::EncounterStream& stream = o->encounter_streams_[name];
    stream.next_seq = r->I32();
    stream.last_utime = r->I64();
    GetMap<int32_t, int64_t>(r, &stream.above);
    stream.gap_since = r->I64();
    stream.expected = version >= kRelayCountsVersion ? r->I32() : 0;
  }
  o->arrivals_ = r->I64();
  o->last_released_.reset();
  if (r->Bool()) o->last_released_ = GetKey(r);
  for (int64_t* v :
       {&o->stats_.released, &o->stats_.late, &o->stats_.silences, &o->stats_.peak_held}) {
    *v = r->I64();
  }
}

}  // namespace anchormap
