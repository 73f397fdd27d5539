#include "common/scan_matching/score_covariance.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <unordered_map>
#include <vector>

#include <Eigen/Dense>

#include "common/scan_matching/pose_refinement.h"

namespace anchormap {

namespace {

Eigen::Matrix3d WindowPrior(const ScoreCovarianceOptions& options) {
  const double xy = 1.0 / (options.window_sigma_xy_m * options.window_sigma_xy_m);
  const double theta = 1.0 / (options.window_sigma_theta_rad * options.window_sigma_theta_rad);
  return Eigen::Vector3d(xy, xy, theta).asDiagonal();
}

}  // namespace

Eigen::Matrix3d ScoreDistributionCovariance(const ReferenceField& field, const PointCloud& query,
                                            const Pose2& pose, const Eigen::Matrix3d& hessian,
                                            const ScoreCovarianceOptions& options) {
  const double var = options.point_sigma_m * options.point_sigma_m;
  Eigen::Matrix3d information = hessian / var;
  information.diagonal() +=
      Eigen::Vector3d(1.0 / (options.window_sigma_xy_m * options.window_sigma_xy_m),
                      1.0 / (options.window_sigma_xy_m * options.window_sigma_xy_m),
                      1.0 / (options.window_sigma_theta_rad * options.window_sigma_theta_rad));
  Eigen::Matrix3d laplace = information.inverse();
  laplace = 0.5 * (laplace + laplace.transpose());
  const Eigen::Matrix3d L = laplace.llt().matrixL();

  constexpr int kHalf = 3;
  std::vector<std::array<int, 3>> offsets;
  std::vector<double> log_weights;
  offsets.reserve(343);
  log_weights.reserve(343);
  const Eigen::Vector3d centre = pose.vector();
  for (int a = -kHalf; a <= kHalf; ++a) {
    for (int b = -kHalf; b <= kHalf; ++b) {
      for (int c = -kHalf; c <= kHalf; ++c) {
        const Eigen::Vector3d xi = centre + L * Eigen::Vector3d(a, b, c);
        const double cost = TruncatedCost(field, query, Pose2::FromVector(xi), options.cutoff_m);
        // The window prior is part of the distribution as well.
        const double prior =
            0.5 * Eigen::Vector3d(a, b, c).dot(L.transpose() * (information - hessian / var) * L *
                                               Eigen::Vector3d(a, b, c));
        offsets.push_back({a, b, c});
        log_weights.push_back(-0.5 * cost / var - prior);
      }
    }
  }
  const double max_log = *std::max_element(log_weights.begin(), log_weights.end());
  double total = 0.0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  Eigen::Matrix3d second = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < offsets.size(); ++i) {
    const double w = std::exp(log_weights[i] - max_log);
    const Eigen::Vector3d z(offsets[i][0], offsets[i][1], offsets[i][2]);
    total += w;
    mean += w * z;
    second += w * z * z.transpose();
  }
  mean /= total;
  Eigen::Matrix3d moment = second / total - mean * mean.transpose();
  Eigen::Matrix3d covariance = L * moment * L.transpose();
  covariance = 0.5 * (covariance + covariance.transpose());
  // The moment of a lattice can be singular (all weight on one sample): the floor keeps the
  // result positive definite.
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(covariance);
  const Eigen::Vector3d values = eigen.eigenvalues().cwiseMax(0.0);
  covariance = eigen.eigenvectors() * values.asDiagonal() * eigen.eigenvectors().transpose();
  covariance.diagonal() +=
      Eigen::Vector3d(options.floor_sigma_xy_m * options.floor_sigma_xy_m,
                      options.floor_sigma_xy_m * options.floor_sigma_xy_m,
                      options.floor_sigma_theta_rad * options.floor_sigma_theta_rad);
  return covariance;
}

ReferenceNoiseTerms ComputeReferenceNoiseTerms(const ReferenceField& field, const PointCloud& query,
                                               const Pose2& pose, double cutoff_m) {
  ReferenceNoiseTerms terms;
  const Eigen::Matrix2d R = pose.rotation();
  const Eigen::Vector2d t = pose.translation();
  const GridGeometry& g = field.geometry();
  std::unordered_map<int, Eigen::Vector3d> b;
  double gain_sum = 0.0;
  for (const Eigen::Vector2d& p : query) {
    const Eigen::Vector2d rp = R * p;
    const Eigen::Vector2d q = rp + t;
    const Eigen::Vector2i cell = g.CellOf(q);
    int ia = 0;
    int ib = 0;
    if (!field.NearestPrimitive(cell.x(), cell.y(), &ia, &ib)) continue;
    const Eigen::Vector2d& va = field.vertex(ia);
    const Eigen::Vector2d& vb = field.vertex(ib);
    const Eigen::Vector2d ab = vb - va;
    double s = 0.0;
    Eigen::Vector2d n;
    if (ia != ib && ab.squaredNorm() > 0.0) {
      s = std::clamp((q - va).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
      n = Eigen::Vector2d(-ab.y(), ab.x()).normalized();
    } else {
      n = q - va;
      if (n.norm() < 1e-9) continue;
      n.normalize();
    }
    if ((va + s * ab - q).norm() > cutoff_m) continue;
    const Eigen::Vector3d a(n.x(), n.y(), n.x() * -rp.y() + n.y() * rp.x());
    auto add = [&b](int vertex, const Eigen::Vector3d& value) {
      auto [it, inserted] = b.emplace(vertex, value);
      if (!inserted) it->second += value;
    };
    add(ia, (1.0 - s) * a);
    if (ib != ia) add(ib, s * a);
    gain_sum += (1.0 - s) * (1.0 - s) + s * s;
    ++terms.matched;
  }
  for (const auto& [vertex, value] : b) terms.b_outer += value * value.transpose();
  if (terms.matched > 0) terms.interpolation_gain = gain_sum / terms.matched;
  return terms;
}

Eigen::Matrix3d ReferenceNoiseCovariance(const ReferenceNoiseTerms& terms,
                                         const Eigen::Matrix3d& hessian, double point_sigma_m,
                                         const ScoreCovarianceOptions& options) {
  const double var = point_sigma_m * point_sigma_m;
  const Eigen::Matrix3d P = (hessian / var + WindowPrior(options)).inverse();
  Eigen::Matrix3d covariance = P * terms.b_outer * P / var;
  return 0.5 * (covariance + covariance.transpose());
}

}  // namespace anchormap
