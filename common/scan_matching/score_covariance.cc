#include "common/scan_matching/score_covariance.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <memory_resource>
#include <unordered_map>
#include <vector>

#include <Eigen/Dense>

#include "common/scan_matching/pose_refinement.h"

namespace anchormap {

namespace {

// Directions with less than this fraction of the best-constrained direction's information are
// treated as unconstrained (Zhang, Kaess and Singh, "On degeneracy of optimization-based state
// estimation problems", ICRA 2016): in a corridor the along-wall "information" is the noise of
// the fitted wall normals and the ends of the reference's range, not geometry (measured: 1/260
// of the across-wall information in a 2 m corridor).
constexpr double kDegenerateRatio = 0.02;

Eigen::Matrix3d WindowPrior(const ScoreCovarianceOptions& options) {
  const double xy = 1.0 / (options.window_sigma_xy_m * options.window_sigma_xy_m);
  const double theta = 1.0 / (options.window_sigma_theta_rad * options.window_sigma_theta_rad);
  return Eigen::Vector3d(xy, xy, theta).asDiagonal();
}

}  // namespace

Eigen::Matrix3d DegeneracyFiltered(const Eigen::Matrix3d& hessian, const PointCloud& query) {
  // Heading in metres at the query's RMS range, so that the three axes compare.
  double sum_sq = 0.0;
  for (const Eigen::Vector2d& p : query) sum_sq += p.squaredNorm();
  const double rho =
      query.empty() ? 1.0 : std::max(std::sqrt(sum_sq / static_cast<double>(query.size())), 0.1);
  const Eigen::Vector3d scale(1.0, 1.0, 1.0 / rho);
  const Eigen::Matrix3d scaled = scale.asDiagonal() * hessian * scale.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(scaled);
  Eigen::Vector3d values = eigen.eigenvalues();
  const double largest = values.maxCoeff();
  for (int i = 0; i < 3; ++i) {
    if (!(values(i) >= kDegenerateRatio * largest)) values(i) = 0.0;
  }
  const Eigen::Matrix3d filtered =
      eigen.eigenvectors() * values.asDiagonal() * eigen.eigenvectors().transpose();
  const Eigen::Vector3d unscale(1.0, 1.0, rho);
  return unscale.asDiagonal() * filtered * unscale.asDiagonal();
}

Eigen::Matrix3d ScoreDistributionCovariance(const ReferenceField& field, const PointCloud& query,
                                            const Pose2& pose, const Eigen::Matrix3d& hessian,
                                            const ScoreCovarianceOptions& options) {
  const double var = options.point_sigma_m * options.point_sigma_m;
  const Eigen::Matrix3d prior_information = WindowPrior(options);
  const Eigen::Matrix3d information = hessian / var + prior_information;
  Eigen::Matrix3d laplace = information.inverse();
  laplace = 0.5 * (laplace + laplace.transpose());
  const Eigen::Matrix3d L = laplace.llt().matrixL();

  const AnchoredCost anchored_cost(field, query, pose, options.cutoff_m);
  // 5 samples per axis, 1.5 standard deviations apart, reach the same +-3 sigma as 7 at one
  // sigma with 125 evaluations of the cost instead of 343 (the cost is most of a match's):
  // on a Gaussian the lattice's moment is 0.994 of the variance against 0.996.
  constexpr int kHalf = 2;
  constexpr double kStep = 1.5;
  constexpr int kSide = 2 * kHalf + 1;
  const Eigen::Matrix3d prior_only = L.transpose() * (information - hessian / var) * L;
  std::array<Eigen::Vector3d, kSide * kSide * kSide> offsets;
  std::array<double, kSide * kSide * kSide> log_weights;
  std::vector<Pose2> samples;
  samples.reserve(offsets.size());
  const Eigen::Vector3d centre = pose.vector();
  size_t count = 0;
  for (int a = -kHalf; a <= kHalf; ++a) {
    for (int b = -kHalf; b <= kHalf; ++b) {
      for (int c = -kHalf; c <= kHalf; ++c) {
        const Eigen::Vector3d z = kStep * Eigen::Vector3d(a, b, c);
        offsets[count++] = z;
        samples.push_back(Pose2::FromVector(centre + L * z));
      }
    }
  }
  // All samples' costs at once, point by point (AnchoredCost: the same bits as one by one).
  const std::vector<double> costs = anchored_cost(samples);
  for (size_t i = 0; i < count; ++i) {
    const Eigen::Vector3d& z = offsets[i];
    // The window prior is part of the distribution as well.
    const double prior = 0.5 * z.dot(prior_only * z);
    log_weights[i] = -0.5 * costs[i] / var - prior;
  }
  const double max_log = *std::max_element(log_weights.begin(), log_weights.end());
  double total = 0.0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  Eigen::Matrix3d second = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < count; ++i) {
    const double w = std::exp(log_weights[i] - max_log);
    const Eigen::Vector3d& z = offsets[i];
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
  // Directions the geometry does not constrain (zeroed by DegeneracyFiltered): the samples
  // there follow the noise of the walls, not the pose, so they get the window's spread.
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> hessian_eigen(hessian);
  const double largest = hessian_eigen.eigenvalues().maxCoeff();
  for (int i = 0; i < 3; ++i) {
    if (hessian_eigen.eigenvalues()(i) > 1e-9 * largest) continue;
    const Eigen::Vector3d u = hessian_eigen.eigenvectors().col(i);
    covariance += u * u.transpose() / u.dot(prior_information * u);
  }
  covariance.diagonal() +=
      Eigen::Vector3d(options.floor_sigma_xy_m * options.floor_sigma_xy_m,
                      options.floor_sigma_xy_m * options.floor_sigma_xy_m,
                      options.floor_sigma_theta_rad * options.floor_sigma_theta_rad);
  return covariance;
}

Eigen::Matrix3d LaplaceCovariance(const Eigen::Matrix3d& hessian,
                                  const ScoreCovarianceOptions& options) {
  const double var = options.point_sigma_m * options.point_sigma_m;
  const Eigen::Matrix3d information = hessian / var + WindowPrior(options);
  Eigen::Matrix3d covariance = information.inverse();
  covariance = 0.5 * (covariance + covariance.transpose());
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
  // The nodes come from one buffer, freed at once (a node's malloc and free per matched vertex
  // were most of this function's time). The same table otherwise: its buckets, and so the
  // order the sum below takes them in (b_outer's bits), depend on the keys and the insertions,
  // not on where the nodes live.
  std::array<std::byte, 32 * 1024> arena;
  std::pmr::monotonic_buffer_resource nodes(arena.data(), arena.size());
  std::pmr::unordered_map<int, Eigen::Vector3d> b(&nodes);
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
    if (ia != ib && ab.squaredNorm() > 0.0)
      s = std::clamp((q - va).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
    if (!field.PrimitiveNormal(ia, ib, &n)) {
      n = q - va;
      if (n.norm() < 1e-9) continue;
      n.normalize();
    }
    if ((va + s * ab - q).norm() > cutoff_m) continue;
    const Eigen::Vector3d a(n.x(), n.y(), n.x() * -rp.y() + n.y() * rp.x());
    // A reference point's noise moves it along its own normal: its sign decides the sign of
    // its effect on this residual.
    auto add = [&b, &field, &n](int vertex, const Eigen::Vector3d& value) {
      const Eigen::Vector3d signed_value =
          field.vertex_normal(vertex).dot(n) < 0.0 ? Eigen::Vector3d(-value) : value;
      auto [it, inserted] = b.emplace(vertex, signed_value);
      if (!inserted) it->second += signed_value;
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
                                         const ScoreCovarianceOptions& /*options*/) {
  // The least-squares error from the reference's noise is H^+ (sum_v b_v b_v^T) H^+ sigma^2;
  // the pseudo-inverse leaves degenerate directions (zeroed by DegeneracyFiltered) to the
  // score distribution and its window prior.
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(hessian);
  const Eigen::Vector3d values = eigen.eigenvalues();
  const double largest = values.maxCoeff();
  Eigen::Vector3d inverse = Eigen::Vector3d::Zero();
  for (int i = 0; i < 3; ++i) {
    if (values(i) > 1e-9 * largest && values(i) > 0.0) inverse(i) = 1.0 / values(i);
  }
  const Eigen::Matrix3d H_plus =
      eigen.eigenvectors() * inverse.asDiagonal() * eigen.eigenvectors().transpose();
  Eigen::Matrix3d covariance = point_sigma_m * point_sigma_m * H_plus * terms.b_outer * H_plus;
  return 0.5 * (covariance + covariance.transpose());
}

}  // namespace anchormap
