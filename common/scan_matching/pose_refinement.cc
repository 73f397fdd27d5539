#include "common/scan_matching/pose_refinement.h"

#include <algorithm>

#include <Eigen/Dense>

namespace anchormap {

namespace {

// Accumulates the normal equations at `pose`; returns the truncated cost.
double Linearise(const ReferenceField& field, const PointCloud& query, const Pose2& pose,
                 double cutoff_m, Eigen::Matrix3d* H, Eigen::Vector3d* b, int* inliers) {
  const Eigen::Matrix2d R = pose.rotation();
  const Eigen::Vector2d t = pose.translation();
  const double cutoff_sq = cutoff_m * cutoff_m;
  H->setZero();
  b->setZero();
  *inliers = 0;
  double cost = 0.0;
  for (const Eigen::Vector2d& p : query) {
    const Eigen::Vector2d rp = R * p;
    Eigen::Vector2d v;
    Eigen::Matrix2d J;
    if (!field.Interpolate(rp + t, &v, &J) || v.squaredNorm() > cutoff_sq) {
      cost += cutoff_sq;
      continue;
    }
    cost += v.squaredNorm();
    ++*inliers;
    // residual e = -v(q), q = R p + t: de/dxi = -J [I, (-rp.y, rp.x)].
    Eigen::Matrix<double, 2, 3> dq;
    dq << 1.0, 0.0, -rp.y(), 0.0, 1.0, rp.x();
    const Eigen::Matrix<double, 2, 3> A = -J * dq;
    *H += A.transpose() * A;
    *b += A.transpose() * v;  // -A^T e
  }
  return cost;
}

}  // namespace

double TruncatedCost(const ReferenceField& field, const PointCloud& query, const Pose2& pose,
                     double cutoff_m, int* inliers) {
  const Eigen::Matrix2d R = pose.rotation();
  const Eigen::Vector2d t = pose.translation();
  const double cutoff_sq = cutoff_m * cutoff_m;
  double cost = 0.0;
  int count = 0;
  for (const Eigen::Vector2d& p : query) {
    Eigen::Vector2d v;
    if (field.Interpolate(R * p + t, &v) && v.squaredNorm() <= cutoff_sq) {
      cost += v.squaredNorm();
      ++count;
    } else {
      cost += cutoff_sq;
    }
  }
  if (inliers != nullptr) *inliers = count;
  return cost;
}

RefinementResult RefinePose(const ReferenceField& field, const PointCloud& query,
                            const Pose2& initial, const RefinementOptions& options) {
  RefinementResult result;
  result.pose = initial;
  Eigen::Matrix3d H;
  Eigen::Vector3d b;
  int inliers = 0;
  double cost = Linearise(field, query, result.pose, options.cutoff_m, &H, &b, &inliers);
  result.hessian = H;
  result.inliers = inliers;
  // Levenberg-Marquardt: a step that does not lower the cost is retried with more damping
  // (a degenerate direction, a corridor, must not jump).
  double lambda = 1e-4;
  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    if (inliers < 3) break;
    Eigen::Matrix3d damped = H;
    damped.diagonal() += lambda * (H.diagonal().array() + 1e-9).matrix();
    const Eigen::Vector3d step = damped.ldlt().solve(b);
    if (!step.allFinite()) break;
    const Pose2 candidate = Pose2::FromVector(result.pose.vector() + step);
    Eigen::Matrix3d H_new;
    Eigen::Vector3d b_new;
    int inliers_new = 0;
    const double cost_new =
        Linearise(field, query, candidate, options.cutoff_m, &H_new, &b_new, &inliers_new);
    result.iterations = iteration + 1;
    if (!(cost_new < cost)) {
      lambda *= 10.0;
      if (lambda > 1e6) break;
      continue;
    }
    lambda = std::max(lambda * 0.1, 1e-9);
    result.pose = candidate;
    result.hessian = H_new;
    result.inliers = inliers_new;
    cost = cost_new;
    H = H_new;
    b = b_new;
    inliers = inliers_new;
    if (step.norm() < options.min_step) break;
  }
  if (result.inliers > 3) {
    result.residual_variance = (cost - (static_cast<double>(query.size()) - result.inliers) *
                                           options.cutoff_m * options.cutoff_m) /
                               (result.inliers - 3);
  }
  return result;
}

}  // namespace anchormap
