#pragma once
// A candidate encounter found by scan matching (a match of one trajectory's keyframe in
// another's submap), and what the scan encounters do with one whatever their stage: turn it
// round, test two for pairwise consistency, gate one against the estimate, enter one into
// the graph.

#include <cstdint>
#include <functional>
#include <string>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/solver/keys.h"
#include "server/encounter_source.h"
#include "server/scan_encounter_options.h"
#include "server/scan_encounter_state.h"

namespace anchormap {

// A candidate encounter: keyframe b measured in the frame of keyframe a.
struct EncounterCandidate {
  PoseKey a;
  PoseKey b;
  Pose2 T_a_b;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
  int64_t utime = 0;
  // The keyframe whose scan was the query (b unless the candidate was turned round): two
  // candidates from one query scan are one piece of evidence, not two.
  bool a_is_query = false;
  PoseKey query() const { return a_is_query ? a : b; }
};

// The largest standard deviation of a 2 x 2 covariance (its largest eigenvalue's root).
double LargestSigma(const Eigen::Matrix2d& covariance);

// A match localised in every direction: no position sigma above max_sigma_m, the heading's
// not above max_sigma_rad (a corridor's match, free along it, is not).
bool Localised(const Eigen::Matrix3d& covariance, double max_sigma_m, double max_sigma_rad);

// The same candidate seen from the other side: a measured in the frame of b.
EncounterCandidate Reversed(const EncounterCandidate& c);

// `c` oriented like `like`: its a in the frame of like's a.
EncounterCandidate OrientedLike(const EncounterCandidate& c, const EncounterCandidate& like,
                                const Smoother& smoother);

// The path a keyframe's odometry drove from its trajectory's first keyframe.
using DrivenToFn = std::function<double(PoseKey)>;

// The pairwise test's statistic of two candidates of one pair, both oriented a in one
// trajectory (+inf when a relative pose is not known): the loop candidate 1, the estimate in
// one, candidate 2 reversed, the estimate in the other. Each trajectory's estimate between
// the two is widened by `drift_per_m` (x, y) and `drift_rad_per_m` (heading) per metre driven
// between them (`driven_to`) and by `drift_rad_per_rad` per radian it turned.
double PairwiseChi2(const EncounterCandidate& c1, const EncounterCandidate& c2,
                    const GraphView& graph, const DrivenToFn& driven_to, double drift_per_m,
                    double drift_rad_per_m, double drift_rad_per_rad = 0.0);

// True when the chi-square gate against the estimate (gate_chi2) accepts `candidate`;
// `widened`: the prediction's covariance widened in every direction by its largest
// translational sigma (the wide near search's matches); `drift` is added to it.
bool WithinGate(const EncounterCandidate& candidate, const GraphView& graph, bool widened,
                const Eigen::Matrix3d& drift, const ScanEncounterOptions& options);

// The candidate as a constraint of the scan encounters (source `source_name`), added to `out`.
void Emit(const EncounterCandidate& candidate, const std::string& source_name,
          EncounterSourceOutput* out);

// The candidate as snapshots hold it, and back.
ScanEncounterCandidateState ToState(const EncounterCandidate& c);
EncounterCandidate FromState(const ScanEncounterCandidateState& c);

}  // namespace anchormap
