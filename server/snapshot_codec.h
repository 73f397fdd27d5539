#pragma once
// The server's state as bytes (issue 13: periodic snapshots keep restarts fast): the one
// place that knows the snapshot format. A snapshot is taken between two journal events and
// records which journal prefix it covers (JournalPosition); a restart restores the newest
// valid one and replays only the journal's events after it (server/node/snapshot_store.h).
//
// What it holds: MappingServer's delivery table (sequence windows, held keyframes), the
// keyframes waiting for it, the canonical order stage (its queues, watermarks, encounter
// streams, the last released key), the graph's trajectory table (keyframes with scans),
// the smoother's graph as the ordered list of its edits (GraphEdit: each pose with the
// initial guess it was given live, each measurement), the encounter links, the relayed
// encounters' windows, resend and gap clocks, the direct-encounter source's waiting
// encounters, the counters (stats, refusals by reason); and the node's admitted robots and
// trajectories (its caps). Since version 2 also: the smoother's incremental state
// (common/solver/smoother_state.h: linearisation points, R and d, delta, pending variables
// and factors, the step policy's counters), the match pool's job numbering, and the
// scan-matching sources' state (server/loop_closure_state.h, scan_encounter_state.h: waiting
// keyframes, submap drawings, kept hypotheses and candidates, cooldowns, budgets, counters,
// and the matches in flight with their results, waited for when the snapshot is taken).
// Since version 12 also the reduced graph (server/keyframe_fold.h): the aliases among the
// graph edits (so the measurements on them map onto the same nodes again, and the borrowed
// nodes' numbering and the count of measurements inside one node follow), and the folder's
// node table, position index (as it stands, not rebuilt) and counters. So a
// restored server, scan sources on, continues exactly as the uninterrupted one: the same
// estimate and covariances, hence the same candidates, gates and graph edits (tested to the
// bit: snapshot_codec_test.cc, tests/crash_test.sh mode scan). Not held: the map publisher's
// state (the next map and grid go out whole, as after any restart), the submap references
// (rebuilt from their drawings when needed), memoised covariances, the update timings and
// the match pool's counters (this process's), the once-per-kind log memories, and the
// folder's cache of node scan references (rebuilt from the keyframes' scans: the same
// references, so the same folds).
//
// A version-1 snapshot (direct-encounter source alone) held no smoother state: it is
// restored by one batch step from the live initial guesses, after the journal's tail (the
// converged estimate, as after a deferred journal replay). Only a server whose sources are
// its own (MappingServer::CanSnapshot: no source added with AddEncounterSource) can be
// snapshot.
//
// Format: "AMSNAPSH", version (u32), payload size (u64), payload, FNV-1a 64 of everything
// before it (u64); little-endian. A wrong magic, version, size or checksum, or a payload
// that does not decode to the end, is refused with the reason (kDecodeFailed).

#include <cstddef>
#include <cstdint>
#include <set>
#include <string>
#include <vector>

#include "common/types/trajectory_name.h"
#include "common/util/status.h"
#include "server/mapping_server.h"

namespace anchormap {

// Version 2 adds the smoother's incremental state, the match pool's numbering and the
// scan-matching sources' state; version 3 the keyframes' counts of relayed encounters and
// the per-trajectory counts they revealed (the delivery windows, the order stage's
// encounter streams, the last admitted keyframe's count), and the weak flag of the loop
// closures' kept wide hypotheses. Versions 1 and 2 are still read (every count 0: nothing
// revealed, as the keyframes of that time carried none; no hypothesis weak, as none was).
// Version 4 adds the solve period's state (MappingServerOptions::solve_period_s: the last
// update's data time, inputs pending); older ones read as solved at their newest input.
// Version 5 adds the scan encounters' wide near matches (in flight and held); older ones
// read as having none. Version 6 adds the scan encounters' pairs of trajectories caught up
// (near-searched after they came into one frame); older ones read as every pair in one frame
// caught up. Version 7 adds whether a scan encounter's kept candidate is map-verified; older
// ones read as none being. Version 8 adds the smoother's factors since its last correction
// (its skip test); older ones read as none (the bound they hold stands for them). Version 9
// adds the sources' matching budgets (loop closures, near searches: tokens, each
// trajectory's drive and skips at its last served keyframe); older ones read as none (the
// restored sources keep fresh budgets). Version 10 adds a scan encounter's kept candidate's
// own maps' conflict (what guides a global search); older ones read as not measured.
// Version 11 adds the smoother's local corrections' moves since its last gradient pass
// (correction_local_hops); older ones read as none (server/smoother_state_codec.h).
// Version 12 adds the reduced graph (MappingServerOptions::reduced_graph): the aliases as graph
// edits (GraphEdit::Kind::kAlias, in their order among the others), the smoother's counts of
// aliases and of measurements inside one node (checked on import), the folder's node table,
// position index and counters (keyframe_fold_state.h), and the sources' counts of folded
// keyframes; older ones read as holding no alias (every pose a node of a restored server with
// the option, verified by its own scan) and the counts as 0.
inline constexpr uint32_t kSnapshotVersion = 12;
inline constexpr uint32_t kOldestSnapshotVersion = 1;

// The journal prefix a snapshot covers: its first `events` events, the last of which had
// this time and channel (checked against the journal on restore).
struct JournalPosition {
  int64_t events = 0;
  int64_t last_utime = 0;
  std::string last_channel;
};

// The server node's own state (server/node/server_node.h: the caps' memory).
struct SnapshotNodeState {
  JournalPosition position;
  std::set<std::string> robots;
  std::set<TrajectoryName> trajectories;
};

class SnapshotCodec {
 public:
  // kInvalidArgument when !server.CanSnapshot().
  static Result<std::vector<uint8_t>> Encode(const MappingServer& server,
                                             const SnapshotNodeState& node);
  // The same state in an older format (2 .. kSnapshotVersion), for the tests that it is
  // still read; what that format cannot hold is left out.
  static Result<std::vector<uint8_t>> EncodeVersion(const MappingServer& server,
                                                    const SnapshotNodeState& node,
                                                    uint32_t version);
  // Checks the envelope (magic, version, size, checksum) and reads the journal position.
  static Result<JournalPosition> ReadPosition(const uint8_t* data, size_t size);
  // Restores into `server`, freshly constructed with the options of the server that wrote
  // the snapshot (options are not stored; sources are checked) and given no input. Version
  // 2 and later: the server is as the snapshot's was (solved); the caller replays the journal's
  // tail. Version 1: the server is left deferring its updates (MappingServer::
  // BeginDeferredUpdates) with its graph not yet solved: the caller replays the journal's
  // tail, then EndDeferredUpdates() solves once by a batch step. On an error `server` is
  // unusable (the caller discards it).
  static Status Decode(const uint8_t* data, size_t size, MappingServer* server,
                       SnapshotNodeState* node);
};

}  // namespace anchormap
