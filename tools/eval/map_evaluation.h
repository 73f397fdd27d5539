#pragma once
// Puts the estimate and the references together: ATE / RPE per trajectory (each aligned on its
// own) and for the merged map (one alignment for the largest group of anchored trajectories),
// and the estimate the relations metric runs on. No file access here.

#include <map>
#include <string>
#include <vector>

#include "common/util/status.h"
#include "tools/eval/eval_inputs.h"
#include "tools/eval/eval_report.h"
#include "tools/eval/relations.h"

namespace anchormap {

// Per-trajectory and merged errors. Trajectories of robots without reference poses are
// listed without errors; the merged row exists when the largest anchored group has matches.
AteReport EvaluateAgainstReferences(const MapEstimate& estimate, const ReferenceSet& references,
                                    double max_time_gap_s);

// The poses of robot `robot`'s trajectories ("" = every trajectory) merged in time order, each
// tagged with its frame: its group when anchored, a frame of its own otherwise. Fails when no
// trajectory matches.
Status BuildRelationsEstimate(const MapEstimate& estimate, const std::string& robot,
                              RelationsEstimate* relations_estimate);

// Poses at the relations' times instead of the keyframes: each trajectory is completed with
// its robot's raw odometry (odometry_completion.h) at every relation time t1, t2 within its
// keyframe span (+- max_time_gap_s). Trajectories of robots without odometry keep their
// keyframes; *completed_trajectories counts the others.
struct OdometryCompletion {
  const std::map<std::string, StampedTrajectory>* odometry_by_robot = nullptr;
  const std::vector<Relation>* relations = nullptr;
  double max_time_gap_s = 0.05;
  int* completed_trajectories = nullptr;
};
Status BuildRelationsEstimate(const MapEstimate& estimate, const std::string& robot,
                              const OdometryCompletion& completion,
                              RelationsEstimate* relations_estimate);

}  // namespace anchormap
