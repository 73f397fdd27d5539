#pragma once
// The mapping server's logic, with no bus (docs/ARCHITECTURE.md "A keyframe's path", steps 6-7):
// keyframes and encounters in, the incremental smoother updated after each, outputs as
// plain values. One pose graph per trajectory in its own local frame (the agent's
// odometry frame); a trajectory's anchor appears at its first encounter (the smoother's
// relative formulation, docs/METHOD.md section 4). Encounter sources are pluggable
// (EncounterSource); the direct-encounter source is always present, loop closures and scan
// encounters (scan matching, on worker threads) when switched on. Inputs reach the graph
// through the delivery table and the canonical order stage (CanonicalInputOrder), so the
// graph is built in one order whatever order the bus delivered. Tests drive this class
// directly; ServerNode connects it to bytes and server_main.cc to LCM.

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

#include "common/solver/smoother.h"
#include "common/types/delivery.h"
#include "common/types/encounter.h"
#include "common/types/keyframe.h"
#include "common/types/map_outputs.h"
#include "common/types/trajectory_name.h"
#include "common/util/reject_counter.h"
#include "common/util/status.h"
#include "server/canonical_order.h"
#include "server/delivery.h"
#include "server/direct_encounters.h"
#include "server/encounter_source.h"
#include "server/keyframe_fold.h"
#include "server/loop_closures.h"
#include "server/map_publisher.h"
#include "server/match_pool.h"
#include "server/scan_encounters.h"
#include "server/trajectory_table.h"

namespace anchormap {

// The smoother's defaults: common/solver's ServerModeOptions() (relinearisation and
// merges by partial steps, batch steps only on fill; why there) with the conjugate-gradient
// correction (the estimate kept within a few 1e-4 x chi2 of the optimum by CG steps with R as
// the preconditioner; partial steps only when it stalls): M3500 1.70 s CPU against 4.78 s, the
// same maps on the real logs and the demo (docs/ARCHITECTURE.md, "Correcting the estimate").
// anchormap-bench-solver's equivalent: --server-mode --correct 1e-4 --correct-iterations 5
// --relinearize-on-stall --correct-cg 50.
inline SmootherOptions DefaultServerSmootherOptions() { return ServerModeWithCorrectionOptions(); }

struct MappingServerOptions {
  SmootherOptions smoother = DefaultServerSmootherOptions();
  // Keep every solver update's cost (update_times()): for benchmarks, off in the daemons,
  // whose memory must not grow with the mission.
  bool record_update_times = false;
  TrajectoryTableOptions table;
  DirectEncounterOptions direct;
  // The reorder stage in front of the graph (CanonicalInputOrder): the graph is built in
  // one canonical order of the inputs, whatever order the bus delivered them in.
  CanonicalOrderOptions order;
  // Scan matching on the keyframes' scans (keyframes without a scan are skipped). Their
  // decisions depend on the graph's state when they look; the canonical order makes that
  // state a function of the input set (offline: tested to 1e-9 across interleavings, bit
  // for bit across worker counts). Off here, so that unit tests and library users switch
  // them on where they mean to; on in the daemons (anchormap-server, anchormap-replay:
  // DaemonDefaults in server/node/server_options.h; docs/ARCHITECTURE.md, Defaults).
  bool loop_closures = false;
  LoopClosureOptions loop;
  bool scan_encounters = false;
  ScanEncounterOptions scan;
  // The sources' matching runs on this many worker threads (0: on the server's thread);
  // each result is used once the canonical input reaches its keyframe's time plus the lag
  // (data time), so the map does not depend on the worker count or thread timing. Lag 0:
  // a match is waited for at the next input, so the next candidates are gated against an
  // estimate that has it (Intel, 1 robot: mean relation error 0.037 m at lag 0, 0.056 at
  // 0.5 s, 0.083 at 2 s); a lag lets the workers run ahead at that price.
  int match_workers = 2;
  // The solver's period in data time (the released inputs' utime, so that an offline replay
  // stays a function of its input): the inputs released within one period join the graph
  // as they come, and one smoother update folds them all in once the period has elapsed
  // since the last one, as iSAM is run at a rate rather than per measurement (100 robots
  // send ~150 keyframes per second of data). Earlier when a source must read a solved
  // graph: an anchor or group merge pending while a source reads the estimate, and the end
  // of input. Never on the wall clock (publications, snapshots): the sources' decisions
  // depend on when the graph is solved, and an online server, restarted or not, must reach
  // the map of `anchormap-server --log` on its inputs. A publication between updates shows
  // the inputs since the last one at their initial guesses (the previous estimate and
  // odometry); a snapshot holds the period's state. Sources examine a keyframe once it is
  // solved, so they see it up to one period later. 0: one update per input (here, for
  // tests and library users); the daemons' default is DaemonDefaults'.
  double solve_period_s = 0.0;
  MatchSchedule match_schedule{0.0};
  // The reduced pose graph (server/keyframe_fold.h): a keyframe in an already mapped place
  // folds onto an existing node instead of becoming a variable. Off here, on in the daemons'
  // defaults (server/node/server_options.h, DaemonDefaults). With it on the server never
  // defers updates (the fold reads the estimate); its snapshots hold the aliases (graph
  // edits) and the folder's node table and index (server/snapshot_codec.h).
  ReducedGraphOptions reduced_graph;
  MapPublisherOptions publish;
  DeliveryOptions delivery;

  Status Validate() const {
    if (Status e = delivery.Validate(); !e.ok()) return e;
    if (Status e = smoother.Validate(); !e.ok()) return Status::Error("smoother: " + e.message());
    if (Status e = table.Validate(); !e.ok()) return e;
    if (Status e = order.Validate(); !e.ok()) return e;
    if (Status e = direct.Validate(); !e.ok()) return e;
    if (Status e = loop.Validate(); !e.ok()) return e;
    if (Status e = scan.Validate(); !e.ok()) return e;
    if (Status e = reduced_graph.Validate(); !e.ok()) return e;
    if (match_workers < 0 || match_workers > 64) return Status::Error("match_workers: 0 to 64");
    if (!(match_schedule.lag_s >= 0)) return Status::Error("match lag must be >= 0");
    if (!(solve_period_s >= 0 && solve_period_s <= 3600)) {
      return Status::Error("solve_period_s: 0 to 3600");
    }
    return publish.Validate();
  }
};

struct MappingServerStats {
  int64_t keyframes_received = 0;
  int64_t encounters_received = 0;
  int64_t encounters_added = 0;  // of every kind, loop closures included
  // Added constraints by ConstraintKind (direct, scan encounter, loop closure).
  std::array<int64_t, kNumConstraintKinds> added_by_kind{};
  int64_t updates = 0;
  // Inputs that changed the graph and were left for the next update (solve_period_s).
  int64_t inputs_batched = 0;
  // Of the updates, updates a journal replay deferred (counted, solved by one batch step later).
  int64_t deferred_updates = 0;
  int64_t solver_problems = 0;  // updates whose status was not ok
  double last_update_ms = 0.0;
  double total_update_ms = 0.0;
};

// One call that changed the smoother's graph. MappingServer keeps them in order, so that a
// snapshot (server/snapshot_codec.h) can rebuild the same variables and factors (gauge
// priors, anchors and group merges follow from the order) without the solver's internals.
// The reduced graph's aliases are edits too (kAlias: key a, node b, the offset T_node_key as
// `measured`, its covariance): a measurement on an alias is mapped onto the nodes when it is
// added, so the aliases must be back, in their order, before the measurements that name them.
struct GraphEdit {
  enum class Kind : uint8_t { kPose, kBetween, kEncounter, kAlias };
  Kind kind = Kind::kPose;
  PoseKey a;       // kPose: the new pose; kAlias: the aliased keyframe
  PoseKey b;       // kAlias: its node
  Pose2 measured;  // kPose: the initial guess; kAlias: T_node_key
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
};

// One solver update's cost, when MappingServerOptions::record_update_times is set.
struct UpdateTiming {
  int64_t data_utime = 0;  // the newest input's time when the update ran
  double ms = 0.0;         // the smoother's own wall time for the update
  bool batch_step = false;
  double cpu_ms = 0.0;  // the server thread's CPU time for the update
};

class MappingServer {
 public:
  explicit MappingServer(const MappingServerOptions& options = {});
  ~MappingServer();

  // Adds another encounter source (e.g. scan matching, later); called on every input.
  void AddEncounterSource(std::unique_ptr<EncounterSource> source);

  // Each returns why the input is refused, if it is (already counted). An accepted input
  // goes through the delivery table (sequence order per trajectory) and the canonical
  // order stage; the inputs that stage releases (at most order.release_per_call per
  // call; ReleaseDue, Tick and Flush release the rest) then update the smoother (one
  // incremental update each) before this returns. A duplicate
  // (keyframe seq, or relayed encounter seq, seen before) is refused as
  // kDuplicateSequence and changes nothing.
  Status OnKeyframe(Keyframe keyframe);
  Status OnEncounter(const Encounter& encounter);

  // Reliable delivery. The clock of the gap-hold rule and of resend requests: wall time
  // online (SetClock before each input, Tick on a timer); unset, the data time (offline,
  // deterministic).
  void SetClock(int64_t now_utime) { clock_utime_ = now_utime; }
  int64_t clock_utime() const { return clock_utime_ >= 0 ? clock_utime_ : data_utime_; }
  // Sets the clock, bridges the keyframe gaps that have waited too long (last resort) and
  // releases up to order.release_per_call inputs.
  void Tick(int64_t now_utime);
  // Releases up to `max_inputs` inputs that the canonical order allows at the clock into
  // the graph (one update each); returns how many.
  int ReleaseDue(int max_inputs);
  // One cumulative acknowledgement per known trajectory.
  std::vector<DeliveryAck> BuildAcks() const;
  // Requests for the missing keyframes and relayed encounters of every trajectory that is
  // due again (DeliveryOptions::resend_period_s); counted as published.
  std::vector<ResendRequest> BuildResendRequests();
  // End of input: admits waiting keyframes (bridging gaps), resolves or refuses waiting
  // encounters (when that joins trajectories: solves and has the sources look once more at
  // the joined pairs), updates, and finishes with a batch step (the converged solution).
  void Flush();
  // Runs the update that solve_period_s left pending, if any (Flush calls it; a caller
  // that needs the solved estimate now may too, at the price of determinism online).
  void SolvePending();
  // True when inputs changed the graph since the last update (solve_period_s).
  bool solve_pending() const { return solve_pending_; }
  // Counts a refusal that happened before the logic (e.g. in the codec).
  void CountRejection(const Status& refusal, const std::string& context);

  // Journal replay (crash recovery, server/node): between Begin and End an input that
  // changes the graph adds its variables and factors and counts its update, but the
  // smoother is not solved; End solves once by a batch step. The graphs, tables and
  // counters are the same as with every update run; the estimate is the converged one
  // (what the live run's own next batch step would give), not the incremental one at the
  // crash. A batch step also runs whenever the graph has doubled since the last one, so
  // new poses start from a solved estimate, not from odometry alone, at most twice the
  // cost of the last step. Only when no source reads the estimate (CanDeferUpdates): the
  // scan-matching sources gate their candidates on it, so their replayed decisions would
  // differ from the live ones; Begin then does nothing and every update runs.
  bool CanDeferUpdates() const;
  // False when the updates cannot be deferred; true (nothing changed) when already deferring
  // (e.g. a server restored from a snapshot: server/snapshot_codec.h).
  bool BeginDeferredUpdates();
  // Ends the deferral: the batch step (not counted as an update: it stands for the
  // deferred ones). Ok when nothing was deferred.
  UpdateResult EndDeferredUpdates();
  bool deferring_updates() const { return deferring_; }
  // After a restart's journal replay, before going live at `now_utime` (wall time): the
  // waits measured on the clock (gap holds, the order stage's patience, encounter gaps)
  // count from now at the earliest. A replay that took long (the scan sources' backlog)
  // would otherwise silence robots and bridge gaps the agents are about to resend.
  void ResumeClocks(int64_t now_utime);

  // Periodic snapshots (server/snapshot_codec.h): the state of the server's own sources
  // (direct encounters, loop closures, scan encounters) and of the reduced graph's folder is
  // serialised, so a server with an added source (AddEncounterSource) cannot be snapshot;
  // nor while deferring.
  bool CanSnapshot() const;
  const std::vector<GraphEdit>& graph_edits() const { return graph_edits_; }

  // Outputs from the current estimate, stamped with the newest input time.
  MergedMap BuildMergedMap() const;
  // The merged map as the bus carries it: its header and the chunks due
  // (MapPublisher::SplitMergedMap; `now_utime` on the publications' clock).
  MapChunker::Split SplitMergedMap(int64_t now_utime, bool full);
  AnchorCovariances BuildAnchorCovariances();
  // The trajectories whose anchors BuildAnchorCovariances would publish now (no solve).
  std::vector<TrajectoryId> PublishedAnchors() const;
  // Every tile of the grid, or only the tiles changed since the last grid (MapPublisher;
  // `complete`: every moved keyframe traced again, not only grid_max_moved of them).
  std::vector<GridTile> BuildGridTiles(bool complete = false);
  std::vector<GridTile> BuildChangedGridTiles();
  ServerStatus BuildStatus() const;
  // One line: robots, trajectories, anchored, keyframes, encounters, updates, last update
  // time, waiting items, rejections by reason.
  std::string StatusLine() const;
  // What the publications and the folds cost so far (counters, not in snapshots): grid
  // updates and retraces, map chunks read and sent, the folds' candidates and references.
  std::string WorkLine() const;

  int64_t update_count() const { return stats_.updates; }
  int64_t data_utime() const { return data_utime_; }
  const MappingServerStats& stats() const { return stats_; }
  const std::vector<UpdateTiming>& update_times() const { return update_times_; }
  const Smoother& smoother() const { return smoother_; }
  Smoother& mutable_smoother() { return smoother_; }
  // The graph's trajectories (keyframes released into the smoother).
  const TrajectoryTable& table() const { return table_; }
  // The delivery table: what arrived, in sequence order per trajectory (acks, resends).
  const TrajectoryTable& receipt() const { return receipt_; }
  const CanonicalOrderStats& order_stats() const { return order_.stats(); }
  const RejectCounter& rejects() const { return rejects_; }
  const std::vector<EncounterLink>& encounter_links() const { return links_; }
  // The encounters in the graph (of every kind), by the keyframes they tie; rebuilt from the
  // graph edits on a restore.
  const TrajectoryTies& ties() const { return ties_; }
  MapPublisher& publisher() { return publisher_; }
  // The scan-matching sources' workers; their results are journaled and reused on a
  // restart through it (MatchPool::SetRecorder, Preload).
  MatchPool& match_pool() { return *pool_; }
  // The reduced graph's folds (null when the option is off).
  const KeyframeFolder* folder() const { return folder_.get(); }
  // The encounter sources, the direct-encounter one first (tests look at their state).
  std::vector<const EncounterSource*> sources() const;
  int num_anchored() const;

  // The snapshot codec (server/snapshot_codec.cc) reads and restores the private state.
  friend struct SnapshotAccess;

 private:
  // Moves keyframes the delivery table admitted into the canonical order stage.
  void Enqueue(const std::vector<AdmittedKeyframe>& admitted);
  // Applies what the canonical order stage releases at the current clock, at most `limit`
  // inputs (everything waiting, whatever holds it, when `at_end`), one input and one
  // update at a time; returns how many.
  int Release(bool at_end, int limit);
  void ApplyKeyframe(Keyframe keyframe);
  void ApplyEncounter(const Encounter& encounter);
  // Counts (and records, if asked) one solver update.
  void CountUpdate(const UpdateResult& result, double cpu_seconds);
  // Solves after an input changed the graph: one update (at once, or once solve_period_s
  // has elapsed: SolveDue), or (deferring) a count and a batch step when the graph has
  // doubled.
  void Solve();
  // True when the update cannot wait for the period's end: the period elapsed, or a
  // source that reads the estimate would otherwise see anchors or merges R lacks.
  bool SolveDue() const;
  // One smoother update, counted; the period restarts.
  void RunUpdate();
  // A batch step during a deferral; its problems counted and logged like an update's.
  UpdateResult DeferredBatchStep();
  // Adds admitted keyframes to the smoother and tells the sources.
  void AddKeyframes(const std::vector<AdmittedKeyframe>& admitted, EncounterSourceOutput* found);
  // The frames the graph's trajectories are in (an anchored group's, an unanchored
  // trajectory's own): fewer after a join.
  size_t NumFrames() const;
  // Adds the sources' constraints, counts their refusals, updates the smoother if anything
  // changed.
  void Commit(const EncounterSourceOutput& found, bool changed, const std::string& context);

  MappingServerOptions options_;
  Smoother smoother_;
  // Delivery: sequence order, gaps, acks and resend requests, in arrival order. Its
  // keyframes keep no scan (the stage and the graph table hold them).
  TrajectoryTable receipt_;
  // Keyframes accepted by receipt_ and not yet admitted by it, by (robot, trajectory id,
  // seq, time) (the time tells a restarted agent's reused id apart).
  std::map<std::tuple<std::string, int64_t, int32_t, int64_t>, Keyframe> arrived_;
  CanonicalInputOrder order_;
  // The graph's trajectories: filled in canonical order (solver ids too).
  TrajectoryTable table_;
  MapPublisher publisher_;
  std::unique_ptr<MatchPool> pool_;  // before the sources: it outlives their jobs
  std::vector<std::unique_ptr<EncounterSource>> sources_;
  std::unique_ptr<KeyframeFolder> folder_;  // reduced_graph.enabled
  std::vector<EncounterLink> links_;
  std::vector<GraphEdit> graph_edits_;  // every successful smoother Add*, in order
  TrajectoryTies ties_;                 // the kEncounter edits' keyframes
  RejectCounter rejects_;
  OncePerKindLog solver_log_;
  MappingServerStats stats_;
  // The server thread's CPU seconds by part (WorkLine; not in snapshots).
  struct WorkCpu {
    double fold_s = 0.0;
    double sources_s = 0.0;  // OnKeyframeAdded and Poll after a keyframe
    double map_s = 0.0;
    double covariances_s = 0.0;
    double grid_s = 0.0;
    double solver_s = 0.0;
  };
  WorkCpu work_cpu_;
  std::vector<UpdateTiming> update_times_;
  int64_t data_utime_ = 0;
  int64_t released_utime_ = 0;  // the newest released input's time: the sources' "now"
  int64_t clock_utime_ = -1;
  ResendTracker resend_;
  int64_t resend_requests_ = 0;
  // Relayed encounters' sequence numbers per (observer, observer trajectory id).
  std::map<TrajectoryName, SeqWindow> encounter_seqs_;
  // When each encounter stream's current gap was first seen (clock); after
  // table.max_hold_s the missing encounters are given up (counted, logged).
  std::map<TrajectoryName, int64_t> encounter_gap_since_;
  int64_t encounters_given_up_ = 0;
  bool deferring_ = false;
  int64_t variables_at_deferred_batch_ = 0;  // the graph's size at the last batch step
  bool unsolved_ = false;                    // deferred updates since the last batch step
  // solve_period_s: inputs changed the graph since the last update, and the data time of
  // that update (released_utime_ then).
  bool solve_pending_ = false;
  int64_t last_solve_utime_ = 0;
};

}  // namespace anchormap
