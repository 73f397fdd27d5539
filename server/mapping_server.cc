#include "server/mapping_server.h"

#include <algorithm>
#include <cstdio>
#include <ctime>
#include <set>
#include <string>

#include "common/util/log.h"
#include "server/match_options_fingerprint.h"
#include "server/relative_pose.h"

namespace anchormap {

namespace {

// CPU time of the calling thread: an update's cost that a loaded machine does not inflate
// (wall time counts the time the thread waited for a core).
double ThreadCpuSeconds() {
  timespec now{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &now);
  return static_cast<double>(now.tv_sec) + 1e-9 * static_cast<double>(now.tv_nsec);
}

// Adds the thread's CPU time over its scope to `*total` (the work line's parts).
class ThreadCpuTimer {
 public:
  explicit ThreadCpuTimer(double* total) : total_(total), start_(ThreadCpuSeconds()) {}
  ~ThreadCpuTimer() { *total_ += ThreadCpuSeconds() - start_; }
  ThreadCpuTimer(const ThreadCpuTimer&) = delete;
  ThreadCpuTimer& operator=(const ThreadCpuTimer&) = delete;

 private:
  double* total_;
  double start_;
};

// "keyframe R1/123 seq 4 at 1000000" / "encounter R1/123 seq 2 -> R2 at 1000000".
std::string DescribeInput(const OrderedInput& input) {
  if (input.is_keyframe) {
    const Keyframe& k = input.keyframe;
    return "keyframe " + k.robot + "/" + std::to_string(k.trajectory_id) + " seq " +
           std::to_string(k.seq) + " at " + std::to_string(k.utime);
  }
  const Encounter& e = input.encounter;
  return "encounter " + e.observer + "/" + std::to_string(e.observer_trajectory_id) + " seq " +
         std::to_string(e.seq) + " -> " + e.observed + " at " + std::to_string(e.utime);
}

}  // namespace

MappingServer::MappingServer(const MappingServerOptions& options)
    : options_(options),
      smoother_(options.smoother),
      receipt_(options.table),
      order_(options.order),
      table_(options.table),
      publisher_(options.publish),
      pool_(std::make_unique<MatchPool>(options.match_workers)),
      resend_(options.delivery) {
  // A journaled match is reused only under the options it was computed with.
  pool_->SetOptionsFingerprint(MatchOptionsFingerprint(options));
  sources_.push_back(std::make_unique<DirectEncounters>(options.direct));
  if (options.loop_closures) {
    sources_.push_back(
        std::make_unique<LoopClosures>(options.loop, pool_.get(), options.match_schedule));
  }
  if (options.scan_encounters) {
    ScanEncounterOptions scan = options.scan;
    // A folded keyframe waits for its examination as a new node waits for its solve.
    if (options.reduced_graph.enabled) scan.folded_wait_s = options.solve_period_s;
    sources_.push_back(std::make_unique<ScanEncounters>(scan, pool_.get(), options.match_schedule));
  }
  if (options.reduced_graph.enabled) {
    folder_ = std::make_unique<KeyframeFolder>(options.reduced_graph);
  }
}

MappingServer::~MappingServer() = default;

void MappingServer::AddEncounterSource(std::unique_ptr<EncounterSource> source) {
  sources_.push_back(std::move(source));
}

void MappingServer::CountRejection(const Status& refusal, const std::string& context) {
  rejects_.Count(refusal, context);
}

Status MappingServer::OnKeyframe(Keyframe keyframe) {
  ++stats_.keyframes_received;
  data_utime_ = std::max(data_utime_, keyframe.utime);
  std::vector<AdmittedKeyframe> admitted;
  const int64_t reused_before = receipt_.num_reused_ids();
  const TrajectoryName name{keyframe.robot, keyframe.trajectory_id};
  const int32_t relayed = keyframe.encounters_relayed;
  const auto arrival_key =
      std::make_tuple(keyframe.robot, keyframe.trajectory_id, keyframe.seq, keyframe.utime);
  // The delivery table needs no scan: the keyframe waits here with it until admitted.
  LaserScan scan = std::move(keyframe.scan);
  Keyframe without_scan = keyframe;
  keyframe.scan = std::move(scan);
  if (Status offered = receipt_.Offer(std::move(without_scan), clock_utime(), &admitted);
      !offered.ok()) {
    rejects_.Count(offered, "keyframe");
    return offered;
  }
  arrived_.emplace(arrival_key, std::move(keyframe));
  if (receipt_.num_reused_ids() != reused_before) {
    LogWarning(name.robot + " restarted with the trajectory id " + std::to_string(name.id) +
               " of an earlier session: a new trajectory under the same name");
    encounter_seqs_.erase(name);
  }
  if (relayed > 0) {
    // The encounters relayed before this keyframe: those not here are missing (asked for,
    // and they hold the inputs after them), even with no later encounter to reveal them.
    encounter_seqs_[name].Expect(relayed);
    order_.ExpectEncounters(name.robot, name.id, relayed, clock_utime());
  }
  if (const TrajectoryRecord* record = receipt_.Find(name)) {
    order_.Heard(record->solver_id, clock_utime());
  }
  receipt_.Poll(clock_utime(), &admitted);
  Enqueue(admitted);
  Release(/*at_end=*/false, options_.order.release_per_call);
  return Status::Ok();
}

Status MappingServer::OnEncounter(const Encounter& encounter) {
  ++stats_.encounters_received;
  data_utime_ = std::max(data_utime_, encounter.utime);
  if (encounter.observer == encounter.observed) {
    const Status refused =
        Status::Error(ErrorCode::kSelfEncounter, encounter.observer + " observed itself");
    rejects_.Count(refused, "encounter");
    return refused;
  }
  if (encounter.seq >= 0 &&
      !encounter_seqs_[{encounter.observer, encounter.observer_trajectory_id}].Insert(
          encounter.seq)) {
    const Status refused = Status::Error(ErrorCode::kDuplicateSequence,
                                         "encounter " + encounter.observer + " trajectory " +
                                             std::to_string(encounter.observer_trajectory_id) +
                                             " seq " + std::to_string(encounter.seq));
    rejects_.Count(refused, "encounter");
    return refused;
  }
  order_.AddEncounter(encounter, clock_utime());
  Release(/*at_end=*/false, options_.order.release_per_call);
  return Status::Ok();
}

void MappingServer::Enqueue(const std::vector<AdmittedKeyframe>& admitted) {
  for (const AdmittedKeyframe& a : admitted) {
    const TrajectoryRecord* record = receipt_.FindBySolverId(a.key.trajectory);
    const size_t i = static_cast<size_t>(a.key.index);
    const auto it = arrived_.find(std::make_tuple(record->robot, record->agent_trajectory_id,
                                                  record->seqs[i], record->utimes[i]));
    if (it == arrived_.end()) {  // cannot happen: every offered keyframe was kept
      rejects_.Count(ErrorCode::kSolverRejected, "keyframe", "admitted keyframe not kept");
      continue;
    }
    order_.AddKeyframe(a.key.trajectory, std::move(it->second), clock_utime());
    arrived_.erase(it);
  }
}

int MappingServer::ReleaseDue(int max_inputs) { return Release(/*at_end=*/false, max_inputs); }

int MappingServer::Release(bool at_end, int limit) {
  // Settling is for the bus (online: a wall clock is set); offline inputs are complete,
  // unless they are a bus recording (settle_offline: in data time).
  const bool settle = clock_utime_ >= 0 || options_.order.settle_offline;
  int released = 0;
  for (; at_end || released < limit; ++released) {
    std::vector<TrajectoryId> silenced;
    const int64_t late_before = order_.stats().late;
    std::optional<OrderedInput> input =
        at_end ? order_.NextAtEnd() : order_.Next(clock_utime(), settle, &silenced);
    for (const TrajectoryId id : silenced) {
      const TrajectoryRecord* record = receipt_.FindBySolverId(id);
      LogWarning(record->name().ToString() + " silent for " +
                 std::to_string(options_.order.patience_s) +
                 " s: it no longer holds the other trajectories' inputs");
    }
    if (!input) break;
    if (order_.stats().late != late_before) {
      // Said each time: a late input is where a live map may part from the canonical one.
      LogWarning("late input (released after later ones, data time " +
                 std::to_string(released_utime_) + "): " + DescribeInput(*input));
    }
    released_utime_ = std::max(released_utime_, input->utime());
    if (input->is_keyframe) {
      ApplyKeyframe(std::move(input->keyframe));
    } else {
      ApplyEncounter(input->encounter);
    }
  }
  return released;
}

void MappingServer::ApplyKeyframe(Keyframe keyframe) {
  std::vector<AdmittedKeyframe> admitted;
  if (Status offered = table_.Offer(std::move(keyframe), released_utime_, &admitted);
      !offered.ok()) {
    rejects_.Count(offered, "keyframe");
    return;
  }
  // A gap the delivery table bridged (or a trajectory it started late) reaches the graph
  // as a sequence gap: bridged here at once, by the same rule.
  table_.FlushHeld(&admitted);
  EncounterSourceOutput found;
  AddKeyframes(admitted, &found);
  const GraphView graph{table_, smoother_, &smoother_, &ties_};
  {
    const ThreadCpuTimer timed(&work_cpu_.sources_s);
    for (auto& source : sources_) source->Poll(released_utime_, graph, &found);
  }
  Commit(found, !admitted.empty(), "keyframe");
}

void MappingServer::ApplyEncounter(const Encounter& encounter) {
  EncounterSourceOutput found;
  const GraphView graph{table_, smoother_, &smoother_, &ties_};
  for (auto& source : sources_) {
    source->OnEncounterMessage(encounter, graph, &found);
    source->Poll(released_utime_, graph, &found);
  }
  Commit(found, false, "encounter");
}

void MappingServer::Tick(int64_t now_utime) {
  SetClock(now_utime);
  std::vector<AdmittedKeyframe> admitted;
  receipt_.Poll(clock_utime(), &admitted);
  Enqueue(admitted);
  Release(/*at_end=*/false, options_.order.release_per_call);
}

std::vector<DeliveryAck> MappingServer::BuildAcks() const {
  std::map<TrajectoryName, DeliveryAck> acks;
  auto ack_for = [&](const TrajectoryName& trajectory) -> DeliveryAck& {
    DeliveryAck& ack = acks[trajectory];
    ack.utime = clock_utime();
    ack.robot = trajectory.robot;
    ack.trajectory_id = trajectory.id;
    return ack;
  };
  for (const TrajectoryRecord& record : receipt_.records()) {
    ack_for(record.name()).keyframes_next = receipt_.NextSeq(record.solver_id);
  }
  for (const auto& [key, window] : encounter_seqs_) {
    ack_for(key).encounters_next = window.next();
  }
  std::vector<DeliveryAck> out;
  for (auto& [key, ack] : acks) out.push_back(std::move(ack));
  return out;
}

std::vector<ResendRequest> MappingServer::BuildResendRequests() {
  std::map<TrajectoryName, ResendRequest> requests;
  auto add = [&](const TrajectoryName& trajectory, StreamKind kind,
                 const std::vector<std::pair<int32_t, int32_t>>& ranges) {
    if (ranges.empty()) return;
    ResendRequest& request = requests[trajectory];
    request.utime = clock_utime();
    request.robot = trajectory.robot;
    request.trajectory_id = trajectory.id;
    for (const auto& [first, last] : ranges) request.ranges.push_back({kind, first, last});
  };
  for (const TrajectoryRecord& record : receipt_.records()) {
    add(record.name(), StreamKind::kKeyframes, receipt_.MissingRanges(record.solver_id));
  }
  for (auto& [key, window] : encounter_seqs_) {
    const auto missing = window.Missing();
    if (missing.empty()) {
      encounter_gap_since_.erase(key);
      continue;
    }
    const int64_t since = encounter_gap_since_.emplace(key, clock_utime()).first->second;
    if (1e-6 * static_cast<double>(clock_utime() - since) > options_.table.max_hold_s) {
      const int32_t given_up = window.GiveUpMissing();
      encounters_given_up_ += given_up;
      encounter_gap_since_.erase(key);
      LogWarning("gave up " + std::to_string(given_up) + " missing encounters of " + key.robot +
                 " trajectory " + std::to_string(key.id) + " (not resent in time)");
      continue;
    }
    add(key, StreamKind::kEncounters, missing);
  }
  std::vector<ResendRequest> out;
  for (auto& [key, request] : requests) {
    if (!resend_.Due(key, clock_utime())) continue;
    LogDebug("asking " + key.ToString() + " for " + std::to_string(request.ranges.size()) +
             " missing ranges");
    ++resend_requests_;
    out.push_back(std::move(request));
  }
  return out;
}

void MappingServer::Flush() {
  std::vector<AdmittedKeyframe> admitted;
  receipt_.FlushHeld(&admitted);
  Enqueue(admitted);
  Release(/*at_end=*/true, 0);
  SolvePending();  // the sources' last look reads a solved graph
  // When what the sources resolve joins trajectories, the join is solved and they look once
  // more, as at the next input after a join mid-run (a scan source gates the pair's kept
  // candidates and near-searches the keyframes examined before it); a join made at that second
  // look is not looked at again: two looks at most.
  for (int look = 0; look < 2; ++look) {
    if (look > 0) SolvePending();
    const size_t frames = NumFrames();
    EncounterSourceOutput found;
    const GraphView graph{table_, smoother_, &smoother_, &ties_};
    for (auto& source : sources_) source->Flush(graph, &found);
    Commit(found, false, "flush");
    if (NumFrames() == frames) break;
  }
  // End of input: one batch step, so that the last map is the converged solution rather
  // than the incremental estimate (which relinearises only at batch steps).
  // The batch step folds in what a period left pending.
  solve_pending_ = false;
  last_solve_utime_ = released_utime_;
  if (smoother_.stats().variables > 0) {
    const double cpu_start = ThreadCpuSeconds();
    const UpdateResult result = smoother_.BatchOptimize();
    CountUpdate(result, ThreadCpuSeconds() - cpu_start);
  }
}

void MappingServer::CountUpdate(const UpdateResult& result, double cpu_seconds) {
  ++stats_.updates;
  work_cpu_.solver_s += cpu_seconds;
  stats_.last_update_ms = 1e3 * result.seconds;
  stats_.total_update_ms += stats_.last_update_ms;
  if (options_.record_update_times) {
    update_times_.push_back(
        {data_utime_, stats_.last_update_ms, result.batch_step, 1e3 * cpu_seconds});
  }
}

void MappingServer::AddKeyframes(const std::vector<AdmittedKeyframe>& admitted,
                                 EncounterSourceOutput* found) {
  for (const AdmittedKeyframe& a : admitted) {
    if (a.bridged_gap) {
      const TrajectoryRecord* record = table_.FindBySolverId(a.key.trajectory);
      LogWarning("bridged a gap of " + std::to_string(a.missing_steps) + " keyframes in " +
                 record->robot + " trajectory " + std::to_string(record->agent_trajectory_id) +
                 " before index " + std::to_string(a.key.index) +
                 " (not resent in time: the map lacks them)");
    }
    // Initial guess: the current estimate of the previous pose composed with the odometry
    // delta, not the agent's raw odometry pose. Once encounters have corrected the local
    // trajectory the raw pose is off by that correction, and iSAM would linearise the new
    // rows there until the next batch step (measured: anchor covariances 10-35 % low).
    const Pose2 initial = a.previous && smoother_.HasPose(*a.previous)
                              ? Compose(smoother_.FramePose(*a.previous), a.T_previous_this)
                              : a.T_local_pose;
    // The reduced graph: a keyframe in a mapped place folds onto a node (no variable; its
    // odometry below then joins the nodes, or nothing when it stays on one node).
    std::optional<KeyframeFold> fold;
    if (folder_ && a.previous && smoother_.HasPose(*a.previous)) {
      const ThreadCpuTimer timed(&work_cpu_.fold_s);
      fold = folder_->Decide(a.key, *a.previous, a.T_previous_this, a.T_previous_this_covariance,
                             table_, &smoother_);
    }
    // A node after a predecessor folded onto another trajectory's node is borrowed from that
    // trajectory (a pose of it, tied by a between factor: pose_aliases.h says why).
    const PoseAlias* previous_alias =
        folder_ && a.previous ? smoother_.FindAlias(*a.previous) : nullptr;
    const bool borrowed =
        !fold && previous_alias != nullptr && previous_alias->node.trajectory != a.key.trajectory;
    const PoseKey node =
        borrowed ? smoother_.NextBorrowedNode(previous_alias->node.trajectory) : a.key;
    const Pose2 node_initial = borrowed
                                   ? Compose(smoother_.FramePose(previous_alias->node),
                                             Compose(previous_alias->T_node_key, a.T_previous_this))
                                   : initial;
    Status status = Status::Ok();
    if (fold) {
      status = smoother_.AddAlias(a.key, fold->node, fold->T_node_keyframe, fold->covariance);
      if (status.ok()) {
        graph_edits_.push_back(
            {GraphEdit::Kind::kAlias, a.key, fold->node, fold->T_node_keyframe, fold->covariance});
      }
    } else {
      status = smoother_.AddPose(node, node_initial);
      if (status.ok()) {
        graph_edits_.push_back(
            {GraphEdit::Kind::kPose, node, node, node_initial, Eigen::Matrix3d::Identity()});
        if (folder_) folder_->AddNode(node, a.key, smoother_);
      }
      if (status.ok() && borrowed) {
        status = smoother_.AddAlias(a.key, node, Pose2(), Eigen::Matrix3d::Zero());
        if (status.ok()) {
          graph_edits_.push_back(
              {GraphEdit::Kind::kAlias, a.key, node, Pose2(), Eigen::Matrix3d::Zero()});
        }
      }
    }
    if (status.ok() && a.previous) {
      status =
          smoother_.AddBetween(*a.previous, a.key, a.T_previous_this, a.T_previous_this_covariance);
      if (status.ok()) {
        graph_edits_.push_back({GraphEdit::Kind::kBetween, *a.previous, a.key, a.T_previous_this,
                                a.T_previous_this_covariance});
      }
    }
    if (!status.ok()) {
      // The codec validated the numbers, so this is an inconsistency worth seeing.
      rejects_.Count(ErrorCode::kSolverRejected, "keyframe", status.message());
      continue;
    }
    const GraphView graph{table_, smoother_, &smoother_, &ties_};
    const ThreadCpuTimer timed(&work_cpu_.sources_s);
    for (auto& source : sources_) source->OnKeyframeAdded(a.key, graph, found);
  }
}

void MappingServer::Commit(const EncounterSourceOutput& found, bool changed,
                           const std::string& context) {
  for (const Status& refused : found.rejections) rejects_.Count(refused, context);
  for (const EncounterConstraint& c : found.constraints) {
    // A loop closure stays inside its trajectory's local frame: a between factor.
    const bool within = c.a.trajectory == c.b.trajectory;
    const bool first =
        !within && (!smoother_.IsAnchored(c.a.trajectory) || !smoother_.IsAnchored(c.b.trajectory));
    const Status status = within ? smoother_.AddBetween(c.a, c.b, c.measured_T_a_b, c.covariance)
                                 : smoother_.AddEncounter(c.a, c.b, c.measured_T_a_b, c.covariance);
    if (!status.ok()) {
      rejects_.Count(ErrorCode::kSolverRejected, "encounter", status.message());
      continue;
    }
    graph_edits_.push_back({within ? GraphEdit::Kind::kBetween : GraphEdit::Kind::kEncounter, c.a,
                            c.b, c.measured_T_a_b, c.covariance});
    if (!within) ties_.Add(c.a, c.b);
    changed = true;
    ++stats_.encounters_added;
    ++stats_.added_by_kind[static_cast<int>(c.kind)];
    const TrajectoryRecord* a = table_.FindBySolverId(c.a.trajectory);
    const TrajectoryRecord* b = table_.FindBySolverId(c.b.trajectory);
    links_.push_back({a->robot, a->agent_trajectory_id, c.a.index, b->robot, b->agent_trajectory_id,
                      c.b.index, c.kind});
    // Loop closures come by the hundred on a real log: debug level.
    Log(within ? LogLevel::kDebug : LogLevel::kInfo,
        std::string(within ? "loop closure " : "encounter ") + a->robot + "[" +
            std::to_string(c.a.index) + "] -> " + b->robot + "[" + std::to_string(c.b.index) +
            "] (" + c.source + ")" + (first ? ", anchors created" : ""));
  }
  if (changed) Solve();
}

void MappingServer::Solve() {
  if (!deferring_) {
    solve_pending_ = true;
    if (SolveDue()) {
      RunUpdate();
    } else {
      ++stats_.inputs_batched;
    }
    return;
  }
  ++stats_.updates;
  ++stats_.deferred_updates;
  unsolved_ = true;
  // Below 64 variables a batch step is as cheap as the updates it replaces.
  const int64_t variables = smoother_.stats().variables;
  if (variables >= 64 && variables >= 2 * variables_at_deferred_batch_) DeferredBatchStep();
}

bool MappingServer::SolveDue() const {
  if (options_.solve_period_s <= 0) return true;
  const double since_s = 1e-6 * static_cast<double>(released_utime_ - last_solve_utime_);
  if (since_s >= options_.solve_period_s) return true;
  // The sources read covariances between inputs: never across a frame R does not hold.
  return smoother_.GroupChangePending() && !CanDeferUpdates();
}

void MappingServer::RunUpdate() {
  solve_pending_ = false;
  last_solve_utime_ = released_utime_;
  const double cpu_start = ThreadCpuSeconds();
  const UpdateResult result = smoother_.Update();
  CountUpdate(result, ThreadCpuSeconds() - cpu_start);
  if (!result.status.ok()) {
    ++stats_.solver_problems;
    solver_log_.Log(LogLevel::kWarning, "solver", "solver update: " + result.status.message());
  }
}

void MappingServer::SolvePending() {
  if (solve_pending_ && !deferring_) RunUpdate();
}

UpdateResult MappingServer::DeferredBatchStep() {
  UpdateResult result = smoother_.BatchOptimize();
  last_solve_utime_ = released_utime_;
  variables_at_deferred_batch_ = smoother_.stats().variables;
  unsolved_ = !result.status.ok();  // a failed step left everything pending: try again
  stats_.last_update_ms = 1e3 * result.seconds;
  stats_.total_update_ms += stats_.last_update_ms;
  if (!result.status.ok()) {
    ++stats_.solver_problems;
    solver_log_.Log(LogLevel::kWarning, "solver",
                    "deferred batch step: " + result.status.message());
  }
  return result;
}

void MappingServer::ResumeClocks(int64_t now_utime) {
  receipt_.ResumeAt(now_utime);
  order_.ResumeAt(now_utime);
  for (auto& [name, since] : encounter_gap_since_) since = std::max(since, now_utime);
}

bool MappingServer::CanDeferUpdates() const {
  // The reduced graph's fold reads the estimate (the prediction, the candidates, the gate's
  // covariance): a deferred replay would fold otherwise than the live run did.
  if (folder_) return false;
  return std::none_of(sources_.begin(), sources_.end(),
                      [](const auto& source) { return source->ReadsEstimate(); });
}

bool MappingServer::CanSnapshot() const {
  if (deferring_ || dynamic_cast<const DirectEncounters*>(sources_.front().get()) == nullptr) {
    return false;
  }
  return std::all_of(sources_.begin() + 1, sources_.end(), [](const auto& source) {
    return dynamic_cast<const LoopClosures*>(source.get()) != nullptr ||
           dynamic_cast<const ScanEncounters*>(source.get()) != nullptr;
  });
}

bool MappingServer::BeginDeferredUpdates() {
  if (deferring_) return true;
  if (!CanDeferUpdates()) return false;
  deferring_ = true;
  // Inputs a period left pending are solved by the deferral's batch step.
  unsolved_ = solve_pending_;
  solve_pending_ = false;
  variables_at_deferred_batch_ = smoother_.stats().variables;
  return true;
}

UpdateResult MappingServer::EndDeferredUpdates() {
  UpdateResult result;
  if (!deferring_) return result;
  deferring_ = false;
  // Nothing changed the graph since the last step: the estimate holds.
  if (!unsolved_) return result;
  return DeferredBatchStep();
}

std::vector<const EncounterSource*> MappingServer::sources() const {
  std::vector<const EncounterSource*> out;
  for (const auto& source : sources_) out.push_back(source.get());
  return out;
}

size_t MappingServer::NumFrames() const {
  std::set<TrajectoryFrame> frames;
  for (const TrajectoryRecord& record : table_.records()) {
    frames.insert(FrameOf(smoother_, record.solver_id));
  }
  return frames.size();
}

int MappingServer::num_anchored() const {
  int anchored = 0;
  for (const TrajectoryRecord& record : table_.records()) {
    if (smoother_.IsAnchored(record.solver_id)) ++anchored;
  }
  return anchored;
}

MergedMap MappingServer::BuildMergedMap() const {
  return publisher_.BuildMergedMap(smoother_, table_, links_, data_utime_, stats_.updates);
}

MapChunker::Split MappingServer::SplitMergedMap(int64_t now_utime, bool full) {
  const ThreadCpuTimer timed(&work_cpu_.map_s);
  return publisher_.SplitMergedMap(smoother_, table_, links_, data_utime_, stats_.updates,
                                   now_utime, full);
}

AnchorCovariances MappingServer::BuildAnchorCovariances() {
  const ThreadCpuTimer timed(&work_cpu_.covariances_s);
  return publisher_.BuildAnchorCovariances(&smoother_, table_, data_utime_, stats_.updates);
}

std::vector<TrajectoryId> MappingServer::PublishedAnchors() const {
  return publisher_.PublishedAnchors(smoother_, table_);
}

std::vector<GridTile> MappingServer::BuildGridTiles(bool complete) {
  const ThreadCpuTimer timed(&work_cpu_.grid_s);
  return publisher_.BuildGridTiles(smoother_, table_, data_utime_, stats_.updates, complete);
}

std::vector<GridTile> MappingServer::BuildChangedGridTiles() {
  const ThreadCpuTimer timed(&work_cpu_.grid_s);
  return publisher_.BuildChangedGridTiles(smoother_, table_, data_utime_, stats_.updates);
}

ServerStatus MappingServer::BuildStatus() const {
  ServerStatus status;
  status.utime = data_utime_;
  status.update = stats_.updates;
  status.num_robots = table_.num_robots();
  status.num_trajectories = static_cast<int32_t>(table_.records().size());
  status.num_anchored = num_anchored();
  status.keyframes = table_.num_keyframes();
  status.encounters = stats_.encounters_added;
  // Offline (no clock set) the outputs are a function of the input alone: a measured time
  // made two replays' bytes differ. The costs stay in the log line and --update-times.
  status.last_update_ms = clock_utime_ >= 0 ? stats_.last_update_ms : 0.0;
  status.bridged_gaps = receipt_.num_bridged_gaps();
  status.resend_requests = resend_requests_;
  status.rejections = rejects_.NonZero();
  return status;
}

std::string MappingServer::WorkLine() const {
  char cpu[160];
  std::snprintf(cpu, sizeof(cpu),
                "cpu s: fold %.3f sources %.3f map %.3f covariances %.3f grid %.3f solver %.3f; ",
                work_cpu_.fold_s, work_cpu_.sources_s, work_cpu_.map_s, work_cpu_.covariances_s,
                work_cpu_.grid_s, work_cpu_.solver_s);
  std::string line = std::string(cpu) + publisher_.WorkSummary();
  if (folder_) line += "; " + folder_->work().Summary();
  return line;
}

std::string MappingServer::StatusLine() const {
  size_t waiting_encounters = 0;
  for (const auto& source : sources_) waiting_encounters += source->pending();
  char text[512];
  std::snprintf(text, sizeof(text),
                "robots %d trajectories %zu anchored %d keyframes %lld encounters %lld "
                "updates %lld last update %.2f ms waiting keyframes %zu encounters %zu "
                "bridged gaps %lld encounters given up %lld resend requests %lld "
                "order: held %zu late %lld silences %lld",
                table_.num_robots(), table_.records().size(), num_anchored(),
                static_cast<long long>(table_.num_keyframes()),
                static_cast<long long>(stats_.encounters_added),
                static_cast<long long>(stats_.updates), stats_.last_update_ms, receipt_.num_held(),
                waiting_encounters, static_cast<long long>(receipt_.num_bridged_gaps()),
                static_cast<long long>(encounters_given_up_),
                static_cast<long long>(resend_requests_), order_.held(),
                static_cast<long long>(order_.stats().late),
                static_cast<long long>(order_.stats().silences));
  // The refusals stay last before the sources' figures: scripts read "rejected: ...".
  const TrajectoryTies::SearchStats& ties = ties_.search_stats();
  std::string line = std::string(text) + " tie searches " + std::to_string(ties.searches) +
                     " settled " + std::to_string(ties.settled) + " most " +
                     std::to_string(ties.most_settled) + " capped " + std::to_string(ties.capped) +
                     " rejected: " + rejects_.Summary();
  for (const auto& source : sources_) {
    const std::string stats = source->StatsLine();
    if (!stats.empty()) line += "; " + stats;
  }
  if (folder_) line += "; " + folder_->StatsLine();
  return line;
}

}  // namespace anchormap
