#include "server/mapping_server.h"

#include <algorithm>
#include <cstdio>

#include "common/util/log.h"

namespace anchormap {

MappingServer::MappingServer(const MappingServerOptions& options)
    : options_(options),
      smoother_(options.smoother),
      table_(options.table),
      publisher_(options.publish) {
  sources_.push_back(std::make_unique<DirectEncounters>(options.direct));
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
  if (Status offered = table_.Offer(std::move(keyframe), &admitted); !offered.ok()) {
    rejects_.Count(offered, "keyframe");
    return offered;
  }
  EncounterSourceOutput found;
  AddKeyframes(admitted, &found);
  const GraphView graph{table_, smoother_};
  for (auto& source : sources_) source->Poll(data_utime_, graph, &found);
  Commit(found, !admitted.empty(), "keyframe");
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
  EncounterSourceOutput found;
  const GraphView graph{table_, smoother_};
  for (auto& source : sources_) {
    source->OnEncounterMessage(encounter, graph, &found);
    source->Poll(data_utime_, graph, &found);
  }
  Commit(found, false, "encounter");
  return Status::Ok();
}

void MappingServer::Flush() {
  std::vector<AdmittedKeyframe> admitted;
  table_.FlushHeld(&admitted);
  EncounterSourceOutput found;
  AddKeyframes(admitted, &found);
  const GraphView graph{table_, smoother_};
  for (auto& source : sources_) source->Flush(graph, &found);
  Commit(found, !admitted.empty(), "flush");
  // End of input: one batch step, so that the last map is the converged solution rather
  // than the incremental estimate (which relinearises only at batch steps).
  if (smoother_.stats().variables > 0) {
    const UpdateResult result = smoother_.BatchOptimize();
    ++stats_.updates;
    stats_.last_update_ms = 1e3 * result.seconds;
    stats_.total_update_ms += stats_.last_update_ms;
  }
}

void MappingServer::AddKeyframes(const std::vector<AdmittedKeyframe>& admitted,
                                 EncounterSourceOutput* found) {
  for (const AdmittedKeyframe& a : admitted) {
    // Initial guess: the current estimate of the previous pose composed with the odometry
    // delta, not the agent's raw odometry pose. Once encounters have corrected the local
    // trajectory the raw pose is off by that correction, and iSAM would linearise the new
    // rows there until the next batch step (measured: anchor covariances 10-35 % low).
    const Pose2 initial = a.previous && smoother_.HasPose(*a.previous)
                              ? Compose(smoother_.LocalPose(*a.previous), a.T_previous_this)
                              : a.T_local_pose;
    Status status = smoother_.AddPose(a.key, initial);
    if (status.ok() && a.previous) {
      status =
          smoother_.AddBetween(*a.previous, a.key, a.T_previous_this, a.T_previous_this_covariance);
    }
    if (!status.ok()) {
      // The codec validated the numbers, so this is an inconsistency worth seeing.
      rejects_.Count(ErrorCode::kSolverRejected, "keyframe", status.message());
      continue;
    }
    const GraphView graph{table_, smoother_};
    for (auto& source : sources_) source->OnKeyframeAdded(a.key, graph, found);
  }
}

void MappingServer::Commit(const EncounterSourceOutput& found, bool changed,
                           const std::string& context) {
  for (const Status& refused : found.rejections) rejects_.Count(refused, context);
  for (const EncounterConstraint& c : found.constraints) {
    const bool first =
        !smoother_.IsAnchored(c.a.trajectory) || !smoother_.IsAnchored(c.b.trajectory);
    const Status status = smoother_.AddEncounter(c.a, c.b, c.measured_T_a_b, c.covariance);
    if (!status.ok()) {
      rejects_.Count(ErrorCode::kSolverRejected, "encounter", status.message());
      continue;
    }
    changed = true;
    ++stats_.encounters_added;
    const TrajectoryRecord* a = table_.FindBySolverId(c.a.trajectory);
    const TrajectoryRecord* b = table_.FindBySolverId(c.b.trajectory);
    links_.push_back({a->agent_trajectory_id, c.a.index, b->agent_trajectory_id, c.b.index});
    LogInfo("encounter " + a->robot + "[" + std::to_string(c.a.index) + "] -> " + b->robot + "[" +
            std::to_string(c.b.index) + "] (" + c.source + ")" +
            (first ? ", anchors created" : ""));
  }
  if (!changed) return;
  const UpdateResult result = smoother_.Update();
  ++stats_.updates;
  stats_.last_update_ms = 1e3 * result.seconds;
  stats_.total_update_ms += stats_.last_update_ms;
  if (!result.status.ok()) {
    ++stats_.solver_problems;
    solver_log_.Log(LogLevel::kWarning, "solver", "solver update: " + result.status.message());
  }
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

AnchorCovariances MappingServer::BuildAnchorCovariances() {
  return publisher_.BuildAnchorCovariances(&smoother_, table_, data_utime_, stats_.updates);
}

std::vector<GridTile> MappingServer::BuildGridTiles() const {
  return publisher_.BuildGridTiles(smoother_, table_, data_utime_, stats_.updates);
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
  status.last_update_ms = stats_.last_update_ms;
  status.rejections = rejects_.NonZero();
  return status;
}

std::string MappingServer::StatusLine() const {
  size_t waiting_encounters = 0;
  for (const auto& source : sources_) waiting_encounters += source->pending();
  char text[256];
  std::snprintf(text, sizeof(text),
                "robots %d trajectories %zu anchored %d keyframes %lld encounters %lld "
                "updates %lld last update %.2f ms waiting keyframes %zu encounters %zu",
                table_.num_robots(), table_.records().size(), num_anchored(),
                static_cast<long long>(table_.num_keyframes()),
                static_cast<long long>(stats_.encounters_added),
                static_cast<long long>(stats_.updates), stats_.last_update_ms, table_.num_held(),
                waiting_encounters);
  return std::string(text) + " rejected: " + rejects_.Summary();
}

}  // namespace anchormap
