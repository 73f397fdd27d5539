#pragma once
// The mapping server between bytes and logic: decodes keyframes and encounters with the
// codec (refusals counted in the server's RejectCounter, per channel), feeds MappingServer,
// and encodes its outputs for a publish callback. The online main connects it to an
// LcmLoop (callback = LCM publish, clock = wall time); the offline main to an LCM log file
// (callback = log writer, clock = data time). No LCM header here: bytes only.
//
// Hostile input is refused here, before the logic sees it (each refusal counted by reason):
// without a valid envelope when authentication is on (unsigned, unknown_key, bad_tag,
// replay), data times ahead of the receive clock (from_future), new robots or
// trajectories past their caps and oversize scans (cap_reached).

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "common/bus/authenticator.h"
#include "common/bus/lcm_log.h"
#include "common/types/trajectory_name.h"

#include "server/mapping_server.h"
#include "server/node/server_options.h"
#include "server/snapshot_codec.h"

namespace anchormap {

class ServerNode {
 public:
  using Publish =
      std::function<void(const std::string& channel, const std::vector<uint8_t>& bytes)>;

  // The receive clock, microseconds (future data times are measured against it).
  using Clock = std::function<int64_t()>;
  static int64_t WallClock();

  ServerNode(const ServerOptions& options, Publish publish, Clock clock = WallClock);

  // From now on inputs must be sealed under `authenticator`'s keys (see server_main.cc for
  // the outputs, which the online main seals with authenticator()).
  void RequireAuthentication(Authenticator authenticator);
  Authenticator* authenticator() { return authenticator_ ? &*authenticator_ : nullptr; }

  // One message; channels other than the keyframe and encounter channels are ignored.
  // Returns true when the channel was one of them.
  bool OnMessage(const std::string& channel, const uint8_t* data, size_t size);

  // Crash recovery (online, --journal; common/bus/journal.h stores the events). From now
  // on every keyframe and encounter that passed this node's checks (envelope opened,
  // decoded, not from the future, within the caps) is given to `append` with the logic's
  // clock before MappingServer sees it (refusals by the logic, such as duplicates, are
  // journaled too and refused again on replay). When `append` fails the input is refused
  // (kIoError) and not applied: unacknowledged, the agent resends it. A Tick that bridged
  // gaps or released inputs from the canonical order stage is appended as a kJournalTick
  // event right after it (nothing is published in between).
  using JournalAppend = std::function<Status(const std::string& channel, int64_t clock_utime,
                                             const uint8_t* data, size_t size)>;
  // Its payload: the number of inputs the tick's release budget let through (int64, host
  // order; empty in older journals: then a replayed tick releases all that is due).
  static constexpr char kJournalTick[] = "ANCHORMAP_JOURNAL_TICK";
  // A restarted server resumed its clocks here (ResumeClocks): replayed at the same point.
  static constexpr char kJournalResume[] = "ANCHORMAP_JOURNAL_RESUME";
  // The scan-matching sources' match results (server/recorded_match_codec.h), appended by the
  // thread that computed one before it is used (MatchPool::SetRecorder): `append` must then
  // be safe to call from several threads. A restart's ReplayJournal reuses them instead of
  // matching again; one that could not be journaled is only logged (a restart recomputes
  // it: the same result, at the matching's cost).
  static constexpr char kJournalMatch[] = "ANCHORMAP_JOURNAL_MATCH";
  // Null: nothing journaled from now on (waits for a match result being journaled).
  void SetJournal(JournalAppend append);
  // Applies one journal event as it was applied live: the logic's clock set to the event's
  // time, the same handlers, nothing appended. Events of other channels are ignored
  // (returns false).
  bool Replay(const LogEvent& event);
  // A restart's replay of the whole journal: Replay for each event, with the solver's
  // updates deferred to batch steps (MappingServer::BeginDeferredUpdates: the same graphs,
  // the converged estimate, a fraction of the CPU) when `defer_updates` and the server's
  // sources allow it, else every update as it ran live.
  struct JournalReplay {
    int64_t events = 0;  // the node's events among those given
    bool deferred = false;
    int64_t matches_journaled = 0;  // match results found in the journal
    int64_t matches_reused = 0;     // of the replay's matches, served from them (not run)
    int64_t matches_run = 0;        // run (not journaled: never run before the crash)
    // Journaled for the ordinal but for another match (another tag): run. 0 unless the
    // journal is replayed with other options than it was written with.
    int64_t matches_mismatched = 0;
    // Journaled for the ordinal but under other matcher / source options (their
    // fingerprint, server/match_options_fingerprint.h), or by a server that recorded none
    // (an older journal): run again, not reused.
    int64_t matches_other_options = 0;
    UpdateResult batch_step;  // the closing batch step, when deferred
  };
  // From events[first] on (the events before it are covered by a restored snapshot).
  JournalReplay ReplayJournal(const std::vector<LogEvent>& events, bool defer_updates,
                              size_t first = 0);
  // Periodic snapshots (server/snapshot_codec.h, snapshot_store.h): the node's and the
  // logic's state after the journal prefix `position`. Only when the server can be
  // snapshot (MappingServer::CanSnapshot: its own sources only, no deferral running).
  bool CanSnapshot() const { return server_->CanSnapshot(); }
  // Waits for the scan sources' matches in flight (their results go into the snapshot):
  // the caller must not hold what the match recorder (SetJournal) takes, e.g. drain the
  // pool first (MatchPool::WaitIdle, as ServerJournal does).
  Result<std::vector<uint8_t>> EncodeSnapshot(const JournalPosition& position) const;
  // Replaces the state by a snapshot's, after checking that `journal` holds the prefix it
  // covers (same length at least, the same last event's time and channel); decoded into a
  // fresh MappingServer, so a refused snapshot changes nothing. Returns the number of
  // journal events it covers. ReplayJournal from there must follow (a version-1 snapshot
  // leaves the server deferring, its graph not yet solved: the replay ends with the batch
  // step).
  Result<int64_t> RestoreSnapshot(const std::vector<uint8_t>& bytes,
                                  const std::vector<LogEvent>& journal);
  // The online timer: the logic's clock, and gaps that waited too long bridged (journaled).
  void Tick(int64_t now_utime);
  // After a restart's replay: the hold and patience clocks count from `now_utime` at the
  // earliest (MappingServer::ResumeClocks), journaled as a kJournalResume event.
  void ResumeClocks(int64_t now_utime);
  // Publishes what is due at `now_utime` (the caller's clock): the merged map after an
  // update (at most once per map period) with the anchor covariances when due (at most once
  // per publish.anchor_covariances_period_s, at once when the anchored trajectories
  // changed), the grid tiles that changed
  // at most once per grid period (every tile once per full grid period).
  void PublishDue(int64_t now_utime);
  void PublishStatus();
  // Online: the merged map and anchor covariances again when none went out for
  // `period_s` (a lost datagram must not leave subscribers with a stale map for long).
  void RepublishMapDue(int64_t now_utime, double period_s);
  // What the kernel dropped on the server's sockets, for the status message (the online
  // main reads it from /proc; stays 0 offline, -1 where it cannot be seen).
  void set_kernel_drops(int64_t drops) { kernel_drops_ = drops; }
  // Stamped on every status message (0 unless set; the online main draws one at random).
  void set_instance_id(int64_t id) { instance_id_ = id; }
  int64_t instance_id() const { return instance_id_; }
  // Publishes map, covariances, grid tiles and status now (end of an offline run).
  void PublishAll();
  // Online delivery: acknowledgements of every trajectory; resend requests that are due.
  void PublishAcks();
  void PublishResendRequests();

  MappingServer& server() { return *server_; }
  int64_t published_maps() const { return published_maps_; }
  int64_t published_grids() const { return published_grids_; }

 private:
  // The merged map's changed chunks (every chunk when `full`), its header, the anchor
  // covariances when due (always with a full map); `now_utime` on the caller's clock (the
  // full map's period, the covariances' period).
  void PublishMap(int64_t now_utime, bool full);
  // Every tile (`full`), or the tiles changed since the last grid.
  // `complete`: the grid brought all the way to the estimate (MapPublisher::UpdateGrid).
  void PublishGrid(bool full, bool complete = false);
  // Decodes and hands on a keyframe or encounter (`data` already out of its envelope);
  // `replaying`: from the journal (checked when it was journaled, not journaled again).
  void Dispatch(const std::string& channel, const uint8_t* data, size_t size, bool replaying);
  void OnKeyframe(Keyframe keyframe, const std::string& channel, const uint8_t* data, size_t size,
                  bool replaying);
  void OnEncounter(const Encounter& encounter, const std::string& channel, const uint8_t* data,
                   size_t size, bool replaying);
  // Appends an input about to be applied; false (refusal counted) when that failed.
  bool Journaled(const std::string& channel, const uint8_t* data, size_t size);
  // Ok when `keyframe` passes the node's checks (time, scan size, caps).
  Status CheckKeyframe(const Keyframe& keyframe) const;
  // Ok when `utime` is not too far ahead of the clock.
  Status CheckNotFuture(int64_t utime) const;
  // Ok when `robot` is known or the robot cap leaves room for it.
  Status CheckRobotCap(const std::string& robot) const;

  ServerOptions options_;
  Publish publish_;
  Clock clock_;
  std::optional<Authenticator> authenticator_;
  JournalAppend journal_;
  // The logic's clock at the last journaled input: the time of match results' events.
  std::shared_ptr<std::atomic<int64_t>> journal_utime_ = std::make_shared<std::atomic<int64_t>>(0);
  std::unique_ptr<MappingServer> server_;  // replaced whole by RestoreSnapshot
  std::set<std::string> robots_;           // admitted, at most options_.max_robots
  std::set<TrajectoryName> trajectories_;  // at most max_trajectories
  int64_t instance_id_ = 0;
  int64_t kernel_drops_ = 0;
  int64_t last_map_utime_ = 0;  // caller's clock of the last map publication (0: none)
  int64_t published_maps_ = 0;
  int64_t published_grids_ = 0;
};

// A journal kept in memory (tests, the journal-replay benchmark): each append becomes one
// event of `journal`. With `mutex` the appends take it, as the match workers append from
// their threads; a reader holds it too while workers may run.
ServerNode::JournalAppend AppendToMemory(std::vector<LogEvent>* journal,
                                         std::mutex* mutex = nullptr);

}  // namespace anchormap
