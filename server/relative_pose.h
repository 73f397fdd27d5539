#pragma once
// The current estimate of keyframe b seen from keyframe a, with its covariance from the
// smoother's joint covariance of the variables involved (docs/METHOD.md section 6): the
// two poses when both are in one trajectory, the two poses and the two anchors when the
// trajectories share an anchored group. It is what a loop-closure or encounter candidate
// is gated against before it may enter the graph.

#include <functional>
#include <optional>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/solver/keys.h"
#include "common/solver/smoother.h"
#include "server/trajectory_table.h"

namespace anchormap {

struct PredictedRelativePose {
  Pose2 T_a_b;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();  // (x, y, theta) of T_a_b
  // The covariance's solve stopped early (the overload with `enough` below): `covariance`
  // is only a lower bound of the exact one.
  bool partial = false;
};

// nullopt when a and b are not in one frame (different groups, or unanchored and in
// different trajectories) or a variable is not solved yet.
std::optional<PredictedRelativePose> PredictRelativePose(Smoother* smoother, PoseKey a, PoseKey b);

// What PredictRelativePose computes before the covariance's solve: T_a_b, and the
// variables and Jacobians of T_a_b whose J Sigma J^T is its covariance (nullopt as there).
// A test that T_a_b alone decides needs no solve.
struct RelativePoseQuery {
  Pose2 T_a_b;
  Smoother::CovarianceQuery covariance;
};
std::optional<RelativePoseQuery> RelativePoseQueryOf(const Smoother& smoother, PoseKey a,
                                                     PoseKey b);

// PredictRelativePose for several pairs, their covariances solved side by side
// (Smoother::ProjectedCovariances, R's rows read once for all): each the bits of
// PredictRelativePose(smoother, a, b).
std::vector<std::optional<PredictedRelativePose>> PredictRelativePoses(
    Smoother* smoother, const std::vector<std::pair<PoseKey, PoseKey>>& pairs);

// The same, the covariance's solve stopped once `enough(T_a_b, covariance so far)` holds
// (Smoother::ProjectedCovarianceUntil; asked before the solve too): then `partial` is set
// and the covariance is a lower bound of the exact one in the positive semidefinite order,
// fit only for a test that gets easier to pass as the covariance grows (a Mahalanobis
// distance under it at most a bound): passed under the bound, it passes under the exact
// covariance. Without a stop, the bits of the overload above.
using EnoughCovariance =
    std::function<bool(const Pose2& T_a_b, const Eigen::Matrix3d& covariance_so_far)>;
std::optional<PredictedRelativePose> PredictRelativePose(Smoother* smoother, PoseKey a, PoseKey b,
                                                         const EnoughCovariance& enough);

// True when a and b are expressed in one frame (same trajectory, or one anchored group).
bool InOneFrame(const Smoother& smoother, TrajectoryId a, TrajectoryId b);

// The frame a trajectory is expressed in, comparable: (true, the group's root) once anchored,
// else (false, itself). InOneFrame(a, b) is FrameOf(a) == FrameOf(b).
using TrajectoryFrame = std::pair<bool, TrajectoryId>;
TrajectoryFrame FrameOf(const Smoother& smoother, TrajectoryId id);
// Each trajectory's frame (FrameOf), in the table's order.
using TrajectoryFrames = std::vector<std::pair<TrajectoryId, TrajectoryFrame>>;
TrajectoryFrames FramesOf(const TrajectoryTable& table, const Smoother& smoother);

// Squared Mahalanobis distance of `measured` from `predicted` under `covariance`
// (the sum of both sides' covariances); +inf when it is not invertible.
double Mahalanobis2(const Pose2& predicted, const Pose2& measured,
                    const Eigen::Matrix3d& covariance);

// Pairwise consistency of two measurements of one pair of trajectories (Mangelson et al.
// 2018): c1 = T_a1_b1 and c2 = T_a2_b2, where a1, a2 lie in one trajectory and b1, b2 in
// another (or the same, for loop closures). c2 is predicted from c1 through the estimates
// a1_a2 = T_a1_a2 and b1_b2 = T_b1_b2; the result is the squared Mahalanobis distance of c2
// from that prediction, under every covariance involved (first order).
double PairwiseInconsistency2(const PredictedRelativePose& a1_a2, const Pose2& c1,
                              const Eigen::Matrix3d& c1_covariance,
                              const PredictedRelativePose& b1_b2, const Pose2& c2,
                              const Eigen::Matrix3d& c2_covariance);

// A matcher's covariance with independent floors added (sigma_m on x and y, sigma_rad on
// theta): scan matches are never trusted below the floors.
inline Eigen::Matrix3d WithCovarianceFloor(Eigen::Matrix3d covariance, double sigma_m,
                                           double sigma_rad) {
  covariance.diagonal() +=
      Eigen::Vector3d(sigma_m * sigma_m, sigma_m * sigma_m, sigma_rad * sigma_rad);
  return covariance;
}

}  // namespace anchormap
