#include "server/encounter_candidate.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <utility>

#include <Eigen/Eigenvalues>

#include "common/solver/smoother.h"
#include "server/relative_pose.h"

namespace anchormap {

double LargestSigma(const Eigen::Matrix2d& covariance) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(covariance);
  return std::sqrt(std::max(0.0, eigen.eigenvalues().maxCoeff()));
}

bool Localised(const Eigen::Matrix3d& covariance, double max_sigma_m, double max_sigma_rad) {
  return LargestSigma(covariance.topLeftCorner<2, 2>()) <= max_sigma_m &&
         std::sqrt(std::max(0.0, covariance(2, 2))) <= max_sigma_rad;
}

EncounterCandidate Reversed(const EncounterCandidate& c) {
  EncounterCandidate r = c;
  std::swap(r.a, r.b);
  r.a_is_query = !c.a_is_query;
  Eigen::Matrix3d J;
  r.T_a_b = Between(c.T_a_b, Pose2(), &J, nullptr);
  r.covariance = J * c.covariance * J.transpose();
  return r;
}

EncounterCandidate OrientedLike(const EncounterCandidate& c, const EncounterCandidate& like,
                                const Smoother& smoother) {
  return InOneFrame(smoother, c.a.trajectory, like.a.trajectory) ? c : Reversed(c);
}

double PairwiseChi2(const EncounterCandidate& c1, const EncounterCandidate& c2,
                    const GraphView& graph, const DrivenToFn& driven_to, double drift_per_m,
                    double drift_rad_per_m, double drift_rad_per_rad) {
  // Within each trajectory, the estimate from c1's keyframe to c2's, with covariance.
  std::optional<PredictedRelativePose> in_a = PredictRelativePose(graph.covariances, c1.a, c2.a);
  std::optional<PredictedRelativePose> in_b = PredictRelativePose(graph.covariances, c1.b, c2.b);
  if (!in_a || !in_b) return std::numeric_limits<double>::infinity();
  if (drift_per_m > 0 || drift_rad_per_m > 0 || drift_rad_per_rad > 0) {
    const auto widen = [&](PoseKey k1, PoseKey k2, PredictedRelativePose* predicted) {
      // In two trajectories of one group (across pairs) no drive: the joint estimate between
      // them rests on their ties, not on odometry alone (ACES split in three sequentially: 125 m
      // through the ties widened the heading by 0.125 rad and let R1[235]-R3[50], 0.2 rad off,
      // confirm the true R2[65]-R3[125]; chi-square 2.8 with the drive, 79 without).
      const double driven =
          k1.trajectory == k2.trajectory ? std::abs(driven_to(k2) - driven_to(k1)) : 0.0;
      const double m = drift_per_m * driven;
      // The estimate's turn between them (wrapped: a full spin counts as none, the safe side).
      const double rad =
          drift_rad_per_m * driven + drift_rad_per_rad * std::abs(predicted->T_a_b.theta());
      predicted->covariance += Eigen::Vector3d(m * m, m * m, rad * rad).asDiagonal();
    };
    widen(c1.a, c2.a, &*in_a);
    widen(c1.b, c2.b, &*in_b);
  }
  return PairwiseInconsistency2(*in_a, c1.T_a_b, c1.covariance, *in_b, c2.T_a_b, c2.covariance);
}

bool WithinGate(const EncounterCandidate& candidate, const GraphView& graph, bool widened,
                const Eigen::Matrix3d& drift, const ScanEncounterOptions& options) {
  const auto passes = [&](const Pose2& T_a_b, const Eigen::Matrix3d& predicted) {
    Eigen::Matrix3d covariance = predicted;
    if (widened) {
      // In every direction by the largest sigma: the estimate of two drifted-apart
      // trajectories is off along axes its covariance does not know.
      const double sigma = LargestSigma(covariance.topLeftCorner<2, 2>());
      covariance.topLeftCorner<2, 2>() += sigma * sigma * Eigen::Matrix2d::Identity();
    }
    return Mahalanobis2(T_a_b, candidate.T_a_b, covariance + drift + candidate.covariance) <=
           options.gate_chi2;
  };
  // The distance only falls as the predicted covariance grows (the widening with it): once
  // a partial sum of its solve passes, the exact covariance passes too, and the rest of
  // the solve (the wide rows at R's bottom) is not needed.
  const std::optional<PredictedRelativePose> predicted =
      PredictRelativePose(graph.covariances, candidate.a, candidate.b, passes);
  if (!predicted) return false;
  return predicted->partial || passes(predicted->T_a_b, predicted->covariance);
}

void Emit(const EncounterCandidate& candidate, const std::string& source_name,
          EncounterSourceOutput* out) {
  EncounterConstraint constraint;
  constraint.a = candidate.a;
  constraint.b = candidate.b;
  constraint.measured_T_a_b = candidate.T_a_b;
  constraint.covariance = candidate.covariance;
  constraint.utime = candidate.utime;
  constraint.source = source_name;
  constraint.kind = ConstraintKind::kScanEncounter;
  out->constraints.push_back(constraint);
}

ScanEncounterCandidateState ToState(const EncounterCandidate& c) {
  return {c.a, c.b, c.T_a_b, c.covariance, c.utime, c.a_is_query};
}

EncounterCandidate FromState(const ScanEncounterCandidateState& c) {
  EncounterCandidate out;
  out.a = c.a;
  out.b = c.b;
  out.T_a_b = c.T_a_b;
  out.covariance = c.covariance;
  out.utime = c.utime;
  out.a_is_query = c.a_is_query;
  return out;
}

}  // namespace anchormap
