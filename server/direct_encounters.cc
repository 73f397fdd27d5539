#include "server/direct_encounters.h"

#include <cmath>
#include <cstdlib>

namespace anchormap {
namespace {

std::string Seconds(int64_t utime) { return std::to_string(1e-6 * static_cast<double>(utime)); }

}  // namespace

Result<EncounterConstraint> TieEncounter(const Encounter& encounter,
                                         const TrajectoryRecord& observer,
                                         const TrajectoryRecord& observed,
                                         const DirectEncounterOptions& options) {
  const int64_t t = encounter.utime;
  const int ia = observer.NearestIndex(t);
  const int ib = observed.NearestIndex(t);
  const double max_offset_us = options.max_time_offset_s * 1e6;
  const int64_t offset_a = std::llabs(observer.utimes[static_cast<size_t>(ia)] - t);
  const int64_t offset_b = std::llabs(observed.utimes[static_cast<size_t>(ib)] - t);
  if (static_cast<double>(offset_a) > max_offset_us ||
      static_cast<double>(offset_b) > max_offset_us) {
    return Status::Error(ErrorCode::kNoKeyframeNearTime,
                         "encounter " + encounter.observer + "->" + encounter.observed + " at " +
                             Seconds(t) + " s: nearest keyframes are " + Seconds(offset_a) +
                             " s and " + Seconds(offset_b) + " s away");
  }
  // Motion between each keyframe and the encounter time, in the keyframe's frame.
  const Pose2 T_ka_ta =
      Between(observer.odometry_poses[static_cast<size_t>(ia)], observer.OdometryPoseAt(t));
  const Pose2 T_kb_tb =
      Between(observed.odometry_poses[static_cast<size_t>(ib)], observed.OdometryPoseAt(t));

  Eigen::Matrix3d J_measurement, J_left, J_right;
  const Pose2 T_ka_tb = Compose(T_ka_ta, encounter.T_observer_observed, nullptr, &J_measurement);
  const Pose2 T_ka_kb = Compose(T_ka_tb, T_kb_tb.Inverse(), &J_left, &J_right);
  // First order: the measurement's covariance rotated into frame ka, plus each
  // correction's noise (the observed side's enters through the second composition).
  Eigen::Matrix3d covariance = J_measurement * encounter.covariance * J_measurement.transpose();
  covariance += options.inflation.Covariance(T_ka_ta);
  covariance = J_left * covariance * J_left.transpose();
  covariance += J_right * options.inflation.Covariance(T_kb_tb) * J_right.transpose();
  covariance = 0.5 * (covariance + covariance.transpose());

  EncounterConstraint constraint;
  constraint.a = PoseKey{observer.solver_id, ia};
  constraint.b = PoseKey{observed.solver_id, ib};
  constraint.measured_T_a_b = T_ka_kb;
  constraint.covariance = covariance;
  constraint.utime = t;
  constraint.source = "direct";
  return constraint;
}

void DirectEncounters::OnEncounterMessage(const Encounter& encounter, const GraphView& graph,
                                          EncounterSourceOutput* out) {
  pending_.push_back(encounter);
  if (pending_.size() > static_cast<size_t>(options_.max_pending)) {
    const Encounter& dropped = pending_.front();
    out->rejections.push_back(Status::Error(
        ErrorCode::kQueueFull, "too many waiting encounters; dropped " + dropped.observer + "->" +
                                   dropped.observed + " at " + Seconds(dropped.utime) + " s"));
    pending_.pop_front();
  }
  Resolve(graph.table, /*flush=*/false, out);
}

void DirectEncounters::OnKeyframeAdded(PoseKey /*key*/, const GraphView& graph,
                                       EncounterSourceOutput* out) {
  if (!pending_.empty()) Resolve(graph.table, /*flush=*/false, out);
}

void DirectEncounters::Poll(int64_t now_utime, const GraphView& graph, EncounterSourceOutput* out) {
  if (now_utime > now_utime_) now_utime_ = now_utime;
  if (!pending_.empty()) Resolve(graph.table, /*flush=*/false, out);
}

void DirectEncounters::Flush(const GraphView& graph, EncounterSourceOutput* out) {
  Resolve(graph.table, /*flush=*/true, out);
}

void DirectEncounters::Resolve(const TrajectoryTable& table, bool flush,
                               EncounterSourceOutput* out) {
  std::deque<Encounter> still_waiting;
  for (const Encounter& e : pending_) {
    const int64_t t = e.utime;
    const TrajectoryRecord* observer = e.observer_trajectory_id != 0
                                           ? table.Find({e.observer, e.observer_trajectory_id})
                                           : table.TrajectoryOfRobotAt(e.observer, t);
    if (observer && observer->num_keyframes() == 0) observer = nullptr;
    const TrajectoryRecord* observed = table.TrajectoryOfRobotAt(e.observed, t);
    const bool timed_out =
        flush || 1e-6 * static_cast<double>(now_utime_ - t) > options_.max_wait_s;
    const std::string name = e.observer + "->" + e.observed + " at " + Seconds(t) + " s";

    if (!observer || !observed) {
      if (!timed_out) {
        still_waiting.push_back(e);
      } else if (!table.TrajectoryOfRobotAt(e.observer, t) ||
                 !table.TrajectoryOfRobotAt(e.observed, t)) {
        out->rejections.push_back(Status::Error(
            ErrorCode::kUnknownRobot, "encounter " + name + " names a robot with no keyframes"));
      } else {
        out->rejections.push_back(Status::Error(ErrorCode::kEncounterTimeout,
                                                "encounter " + name + ": observer trajectory " +
                                                    std::to_string(e.observer_trajectory_id) +
                                                    " unknown"));
      }
      continue;
    }
    const bool keyframes_after = observer->utimes.back() >= t && observed->utimes.back() >= t;
    if (!keyframes_after && !timed_out) {
      still_waiting.push_back(e);
      continue;
    }
    Result<EncounterConstraint> tie = TieEncounter(e, *observer, *observed, options_);
    if (tie.ok()) {
      out->constraints.push_back(std::move(*tie));
    } else {
      out->rejections.push_back(tie.status());
    }
  }
  pending_.swap(still_waiting);
}

}  // namespace anchormap
