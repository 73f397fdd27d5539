#include "tools/eval/relations.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>

#include "common/util/text_fields.h"

namespace anchormap {
namespace {

const std::vector<const char*> kFieldNames = {"t1", "t2", "x", "y", "z", "roll", "pitch", "yaw"};

// Index of the pose nearest in time to `utime` (poses sorted by time, not empty).
size_t Nearest(const StampedTrajectory& poses, int64_t utime) {
  const auto it =
      std::lower_bound(poses.begin(), poses.end(), utime,
                       [](const StampedPose2& pose, int64_t t) { return pose.utime < t; });
  if (it == poses.end()) return poses.size() - 1;
  const size_t after = static_cast<size_t>(it - poses.begin());
  if (after == 0) return 0;
  return (utime - poses[after - 1].utime) <= (it->utime - utime) ? after - 1 : after;
}

}  // namespace

Status ParseRelationLine(std::string_view line, Relation* relation) {
  std::vector<double> v;
  if (Status parsed = ParseNumberFields(line, kFieldNames, /*commas_separate=*/false, &v);
      !parsed.ok()) {
    return parsed;
  }
  relation->t1_s = v[0];
  relation->t2_s = v[1];
  relation->T_1_2 = Pose2(v[2], v[3], v[7]);
  return Status::Ok();
}

Status ReadRelationsFile(const std::string& path, std::vector<Relation>* relations) {
  std::ifstream in(path);
  if (!in) return Status::Error("cannot open relations file '" + path + "'");
  relations->clear();
  std::string line;
  int64_t line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    const auto fields = SplitFields(line);
    if (fields.empty() || fields.front().front() == '#') continue;
    Relation relation;
    if (Status s = ParseRelationLine(line, &relation); !s.ok()) {
      return Status::Error(path + ":" + std::to_string(line_number) + ": " + s.message());
    }
    relations->push_back(relation);
  }
  if (in.bad()) return Status::Error(path + ": read error");
  return Status::Ok();
}

Status RelationsOptions::Validate() const {
  if (!(max_time_gap_s >= 0.0) || !std::isfinite(max_time_gap_s)) {
    return Status::Error("max_time_gap_s: must be a finite number >= 0");
  }
  return Status::Ok();
}

RelationsResult EvaluateRelations(const std::vector<Relation>& relations,
                                  const RelationsEstimate& estimate,
                                  const RelationsOptions& options,
                                  std::vector<RelationError>* per_relation) {
  RelationsResult result;
  result.relations = static_cast<int64_t>(relations.size());
  const StampedTrajectory& poses = estimate.poses;
  const int64_t tolerance_us = std::llround(options.max_time_gap_s * 1e6);
  std::vector<double> translation_errors, rotation_errors;
  for (const Relation& relation : relations) {
    const int64_t t1 = std::llround(relation.t1_s * 1e6);
    const int64_t t2 = std::llround(relation.t2_s * 1e6);
    if (poses.empty() || std::min(t1, t2) < poses.front().utime - tolerance_us ||
        std::max(t1, t2) > poses.back().utime + tolerance_us) {
      ++result.skipped_outside_span;
      continue;
    }
    const size_t i1 = Nearest(poses, t1), i2 = Nearest(poses, t2);
    if (std::abs(poses[i1].utime - t1) > tolerance_us ||
        std::abs(poses[i2].utime - t2) > tolerance_us) {
      ++result.skipped_no_pose_near;
      continue;
    }
    if (!estimate.frame_ids.empty() && estimate.frame_ids[i1] != estimate.frame_ids[i2]) {
      ++result.skipped_across_frames;
      continue;
    }
    const Pose2 estimated = Between(poses[i1].pose, poses[i2].pose);
    translation_errors.push_back((estimated.translation() - relation.T_1_2.translation()).norm());
    rotation_errors.push_back(std::abs(AngleDifference(estimated.theta(), relation.T_1_2.theta())));
    if (per_relation != nullptr) {
      per_relation->push_back({relation.t1_s, relation.t2_s, relation.T_1_2.translation().norm(),
                               translation_errors.back(), rotation_errors.back()});
    }
  }
  result.evaluated = static_cast<int64_t>(translation_errors.size());
  for (size_t i = 0; i < translation_errors.size(); ++i) {
    result.translation_sq_mean_m2 += translation_errors[i] * translation_errors[i];
    result.rotation_sq_mean_rad2 += rotation_errors[i] * rotation_errors[i];
  }
  if (result.evaluated > 0) {
    result.translation_sq_mean_m2 /= static_cast<double>(result.evaluated);
    result.rotation_sq_mean_rad2 /= static_cast<double>(result.evaluated);
  }
  result.translation_m = ComputeErrorStats(std::move(translation_errors));
  result.rotation_rad = ComputeErrorStats(std::move(rotation_errors));
  return result;
}

}  // namespace anchormap
