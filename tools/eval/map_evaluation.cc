#include "tools/eval/map_evaluation.h"

#include "tools/eval/odometry_completion.h"

#include <algorithm>
#include <cmath>
#include <map>

namespace anchormap {
namespace {

std::vector<std::string> Labels(const MapEstimate& estimate) {
  std::map<std::string, int> per_robot;
  for (const auto& t : estimate.trajectories) ++per_robot[t.robot];
  std::vector<std::string> labels;
  for (const auto& t : estimate.trajectories) {
    labels.push_back(per_robot[t.robot] > 1 ? t.robot + "#" + std::to_string(t.trajectory_id)
                                            : t.robot);
  }
  return labels;
}

}  // namespace

AteReport EvaluateAgainstReferences(const MapEstimate& estimate, const ReferenceSet& references,
                                    double max_time_gap_s) {
  AteReport report;
  report.map_update = estimate.update;
  report.num_groups = estimate.num_groups;
  report.max_time_gap_s = max_time_gap_s;
  const int64_t max_gap_us = std::llround(max_time_gap_s * 1e6);
  const std::vector<std::string> labels = Labels(estimate);
  std::vector<std::vector<MatchedPose>> merged_segments;
  for (size_t i = 0; i < estimate.trajectories.size(); ++i) {
    const EstimatedTrajectory& trajectory = estimate.trajectories[i];
    TrajectoryReport row;
    row.label = labels[i];
    row.members = {labels[i]};
    row.anchored = trajectory.anchored;
    row.group = trajectory.group;
    row.poses = static_cast<int64_t>(trajectory.poses.size());
    const auto reference = references.by_robot.find(trajectory.robot);
    if (reference != references.by_robot.end()) {
      row.reference = references.source_by_robot.at(trajectory.robot);
      std::vector<MatchedPose> matched =
          MatchByTime(trajectory.poses, reference->second, max_gap_us, &row.unmatched);
      row.error = ComputeTrajectoryError({matched});
      if (trajectory.anchored && trajectory.group == 0 && !matched.empty()) {
        report.merged.members.push_back(labels[i]);
        report.merged.poses += row.poses;
        report.merged.unmatched += row.unmatched;
        merged_segments.push_back(std::move(matched));
      }
    } else {
      row.unmatched = row.poses;
    }
    report.trajectories.push_back(std::move(row));
  }
  if (!merged_segments.empty()) {
    report.has_merged = true;
    report.merged.label = "merged";
    report.merged.anchored = true;
    report.merged.group = 0;
    report.merged.reference = "per robot";
    report.merged.error = ComputeTrajectoryError(merged_segments);
  }
  return report;
}

Status BuildRelationsEstimate(const MapEstimate& estimate, const std::string& robot,
                              RelationsEstimate* relations_estimate) {
  return BuildRelationsEstimate(estimate, robot, OdometryCompletion(), relations_estimate);
}

Status BuildRelationsEstimate(const MapEstimate& estimate, const std::string& robot,
                              const OdometryCompletion& completion,
                              RelationsEstimate* relations_estimate) {
  *relations_estimate = RelationsEstimate();
  std::vector<int64_t> query_utimes;
  if (completion.odometry_by_robot && completion.relations) {
    for (const Relation& r : *completion.relations) {
      query_utimes.push_back(std::llround(r.t1_s * 1e6));
      query_utimes.push_back(std::llround(r.t2_s * 1e6));
    }
  }
  const int64_t tolerance_us = std::llround(completion.max_time_gap_s * 1e6);
  constexpr int64_t kMaxOdometrySampleGapUs = 1000000;
  if (completion.completed_trajectories) *completion.completed_trajectories = 0;
  std::vector<std::pair<StampedPose2, int>> tagged;
  std::string robots;
  for (size_t i = 0; i < estimate.trajectories.size(); ++i) {
    const EstimatedTrajectory& t = estimate.trajectories[i];
    robots += " " + t.robot;
    if (!robot.empty() && t.robot != robot) continue;
    // Groups are 0..G-1; unanchored trajectories get frames G, G+1, ... of their own.
    const int frame =
        t.anchored && t.group >= 0 ? t.group : estimate.num_groups + static_cast<int>(i);
    const StampedTrajectory* poses = &t.poses;
    StampedTrajectory completed;
    if (!query_utimes.empty()) {
      const auto odometry = completion.odometry_by_robot->find(t.robot);
      if (odometry != completion.odometry_by_robot->end()) {
        completed = CompleteWithOdometry(t.poses, odometry->second, query_utimes, tolerance_us,
                                         kMaxOdometrySampleGapUs);
        poses = &completed;
        if (completion.completed_trajectories) ++*completion.completed_trajectories;
      }
    }
    for (const StampedPose2& pose : *poses) tagged.push_back({pose, frame});
  }
  if (tagged.empty()) {
    return Status::Error(robot.empty() ? "the estimate has no poses"
                                       : "no poses of robot " + robot + " in the estimate " +
                                             "(trajectories of:" + robots + ")");
  }
  std::stable_sort(tagged.begin(), tagged.end(),
                   [](const auto& a, const auto& b) { return a.first.utime < b.first.utime; });
  for (const auto& [pose, frame] : tagged) {
    relations_estimate->poses.push_back(pose);
    relations_estimate->frame_ids.push_back(frame);
  }
  return Status::Ok();
}

}  // namespace anchormap
