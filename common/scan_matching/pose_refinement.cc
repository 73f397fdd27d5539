#include "common/scan_matching/pose_refinement.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

namespace anchormap {

namespace {

// The residual of an inlier at q whose lookup gave the field vector v and, on a wall, the wall's
// normal (null for a lone return).
void ResidualOfInlier(const ReferenceField& field, const Eigen::Vector2d& q, Eigen::Vector2d v,
                      const Eigen::Vector2d* normal, int* rows, Eigen::Vector2d* e,
                      Eigen::Matrix2d* de_dq) {
  if (normal != nullptr) {
    *rows = 1;
    (*e)(0) = -normal->dot(v);
    de_dq->row(0) = normal->transpose();
    return;
  }
  // Only a lone return's residual needs the field's derivative (four divisions per point):
  // asked again with it, the same v.
  Eigen::Matrix2d J;
  field.Interpolate(q, &v, &J);
  *rows = 2;
  *e = -v;
  *de_dq = -J;
}

// One query point's residual e at q and its derivative with respect to q: with a surface
// normal n, the point-to-line distance e = -n.v (one row, the wall's direction left free);
// without (a lone reference return), the point-to-point vector e = -v (two rows). False for an
// outlier (no field there, or the surface farther than the cut-off).
bool PointResidual(const ReferenceField& field, const Eigen::Vector2d& q, double cutoff_sq,
                   int* rows, Eigen::Vector2d* e, Eigen::Matrix2d* de_dq) {
  Eigen::Vector2d v;
  Eigen::Vector2i cell;
  if (!field.InterpolateInCell(q, &v, &cell) || v.squaredNorm() > cutoff_sq) return false;
  Eigen::Vector2d n;
  const bool on_wall = field.NearestNormal(cell.x(), cell.y(), &n);
  ResidualOfInlier(field, q, v, on_wall ? &n : nullptr, rows, e, de_dq);
  return true;
}

// The field's lookups of the query's points at `pose` (R p + t), batched in `at`.
void LookUpAtPose(const ReferenceField& field, const PointCloud& query, const Pose2& pose,
                  ReferenceField::Lookups* at) {
  const Eigen::Matrix2d R = pose.rotation();
  const Eigen::Vector2d t = pose.translation();
  at->resize(query.size());
  for (size_t j = 0; j < query.size(); ++j) {
    const Eigen::Vector2d q = R * query[j] + t;
    at->qx[j] = q.x();
    at->qy[j] = q.y();
  }
  field.InterpolateWithNormals(at);
}

// The truncated cost of the query at the pose `at` was looked up at: every point's
// ResidualOfInlier squared row by row, or cutoff^2 for an outlier, summed in query order
// (NormalEquations' cost, the same bits). A step LM rejects needs only this: more than half
// of an FR079 replay's steps, whose normal equations were built and thrown away.
double CostOfLookups(const ReferenceField::Lookups& at, double cutoff_sq) {
  double cost = 0.0;
  for (size_t j = 0; j < at.qx.size(); ++j) {
    const Eigen::Vector2d v(at.vx[j], at.vy[j]);
    if (!at.found[j] || v.squaredNorm() > cutoff_sq) {
      cost += cutoff_sq;
      continue;
    }
    if (at.has_normal[j]) {
      const double e = -Eigen::Vector2d(at.nx[j], at.ny[j]).dot(v);
      cost += e * e;
    } else {
      // A lone return's residual is -v (ResidualOfInlier asks the field again only for the
      // derivative, and gets the same v).
      cost += v(0) * v(0);
      cost += v(1) * v(1);
    }
  }
  return cost;
}

// Accumulates the normal equations at the pose `at` was looked up at (`pose`); returns the
// truncated cost (CostOfLookups'). PointResidual for every point: the same bits.
double NormalEquations(const ReferenceField& field, const PointCloud& query, const Pose2& pose,
                       double cutoff_m, const ReferenceField::Lookups& at, Eigen::Matrix3d* H,
                       Eigen::Vector3d* b, int* inliers) {
  const Eigen::Matrix2d R = pose.rotation();
  const double cutoff_sq = cutoff_m * cutoff_m;
  b->setZero();
  *inliers = 0;
  double cost = 0.0;
  int rows = 0;
  // Zeroed, though only the first `rows` rows are read: a wall's point sets one row of de_dq
  // and the product below multiplies both. Left uninitialised, the second row held whatever
  // the stack did, subnormal numbers too, whose microcode assists made this loop ~7 % of an
  // FR079 replay's CPU.
  Eigen::Vector2d e = Eigen::Vector2d::Zero();
  Eigen::Matrix2d de_dq = Eigen::Matrix2d::Zero();
  // H's upper triangle, mirrored at the end: a_j a_i is a_i a_j to the bit, so the lower
  // triangle's sums were the same numbers added in the same order.
  double h00 = 0.0, h01 = 0.0, h02 = 0.0, h11 = 0.0, h12 = 0.0, h22 = 0.0;
  for (size_t j = 0; j < query.size(); ++j) {
    const Eigen::Vector2d v(at.vx[j], at.vy[j]);
    if (!at.found[j] || v.squaredNorm() > cutoff_sq) {
      cost += cutoff_sq;
      continue;
    }
    const Eigen::Vector2d rp = R * query[j];
    const Eigen::Vector2d n(at.nx[j], at.ny[j]);
    ResidualOfInlier(field, Eigen::Vector2d(at.qx[j], at.qy[j]), v, at.has_normal[j] ? &n : nullptr,
                     &rows, &e, &de_dq);
    ++*inliers;
    // q = R p + t: dq/dxi = [I, (-rp.y, rp.x)].
    Eigen::Matrix<double, 2, 3> dq;
    dq << 1.0, 0.0, -rp.y(), 0.0, 1.0, rp.x();
    const Eigen::Matrix<double, 2, 3> A = de_dq * dq;
    for (int r = 0; r < rows; ++r) {
      const double a0 = A(r, 0);
      const double a1 = A(r, 1);
      const double a2 = A(r, 2);
      h00 += a0 * a0;
      h01 += a0 * a1;
      h02 += a0 * a2;
      h11 += a1 * a1;
      h12 += a1 * a2;
      h22 += a2 * a2;
      *b -= A.row(r).transpose() * e(r);
      cost += e(r) * e(r);
    }
  }
  *H << h00, h01, h02, h01, h11, h12, h02, h12, h22;
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
  int rows = 0;
  Eigen::Vector2d e;
  Eigen::Matrix2d de_dq;
  for (const Eigen::Vector2d& p : query) {
    if (PointResidual(field, R * p + t, cutoff_sq, &rows, &e, &de_dq)) {
      cost += (rows == 1 ? e(0) * e(0) : e.squaredNorm());
      ++count;
    } else {
      cost += cutoff_sq;
    }
  }
  if (inliers != nullptr) *inliers = count;
  return cost;
}

AnchoredCost::AnchoredCost(const ReferenceField& field, const PointCloud& query,
                           const Pose2& anchor, double cutoff_m)
    : field_(field), query_(query), cutoff_sq_(cutoff_m * cutoff_m) {
  associations_.resize(query.size());
  const Eigen::Matrix2d R = anchor.rotation();
  const Eigen::Vector2d t = anchor.translation();
  for (size_t j = 0; j < query.size(); ++j) {
    const Eigen::Vector2d q = R * query[j] + t;
    Eigen::Vector2d v;
    Eigen::Vector2i cell;
    if (!field.InterpolateInCell(q, &v, &cell) || v.squaredNorm() > cutoff_sq_) continue;
    Association& a = associations_[j];
    a.inlier = true;
    a.surface = q + v;
    a.has_normal = field.NearestNormal(cell.x(), cell.y(), &a.normal);
  }
}

double AnchoredCost::PointCost(const ReferenceField::Lookups& at, size_t i,
                               const Association& a) const {
  if (at.found[i]) {
    const Eigen::Vector2d v(at.vx[i], at.vy[i]);
    if (v.squaredNorm() <= cutoff_sq_) {
      if (at.has_normal[i]) {
        const double along_normal = -Eigen::Vector2d(at.nx[i], at.ny[i]).dot(v);
        return along_normal * along_normal;
      }
      return v.squaredNorm();
    }
  }
  if (!a.inlier) return cutoff_sq_;
  const Eigen::Vector2d q(at.qx[i], at.qy[i]);
  const double sq =
      a.has_normal ? std::pow(a.normal.dot(q - a.surface), 2) : (q - a.surface).squaredNorm();
  return std::min(sq, cutoff_sq_);
}

double AnchoredCost::operator()(const Pose2& pose) const {
  // PointResidual's cost without its Jacobian (the same bits: only the value is needed here,
  // at every point of every sample of the score distribution), the field's lookups batched.
  ReferenceField::Lookups& at = lookups_;
  LookUpAtPose(field_, query_, pose, &at);
  double cost = 0.0;
  for (size_t j = 0; j < query_.size(); ++j) cost += PointCost(at, j, associations_[j]);
  return cost;
}

std::vector<double> AnchoredCost::operator()(const std::vector<Pose2>& poses) const {
  const size_t m = poses.size();
  std::vector<Eigen::Matrix2d> rotations(m);
  std::vector<Eigen::Vector2d> translations(m);
  for (size_t s = 0; s < m; ++s) {
    rotations[s] = poses[s].rotation();
    translations[s] = poses[s].translation();
  }
  std::vector<double> costs(m, 0.0);
  if (m == 0) return costs;
  // Whole steps of four lookups: the last pose's repeated (its answers read once).
  const size_t lanes = (m + 3) / 4 * 4;
  ReferenceField::Lookups& at = lookups_;
  at.resize(lanes);
  for (size_t j = 0; j < query_.size(); ++j) {
    // LookUpAtPose's points, the same expression: point j under every pose.
    for (size_t s = 0; s < m; ++s) {
      const Eigen::Vector2d q = rotations[s] * query_[j] + translations[s];
      at.qx[s] = q.x();
      at.qy[s] = q.y();
    }
    for (size_t s = m; s < lanes; ++s) {
      at.qx[s] = at.qx[m - 1];
      at.qy[s] = at.qy[m - 1];
    }
    field_.InterpolateWithNormals(&at);
    const Association& a = associations_[j];
    for (size_t s = 0; s < m; ++s) costs[s] += PointCost(at, s, a);
  }
  return costs;
}

RefinementResult RefinePose(const ReferenceField& field, const PointCloud& query,
                            const Pose2& initial, const RefinementOptions& options) {
  RefinementResult result;
  result.pose = initial;
  Eigen::Matrix3d H;
  Eigen::Vector3d b;
  int inliers = 0;
  ReferenceField::Lookups lookups;
  const double cutoff_sq = options.cutoff_m * options.cutoff_m;
  LookUpAtPose(field, query, result.pose, &lookups);
  double cost =
      NormalEquations(field, query, result.pose, options.cutoff_m, lookups, &H, &b, &inliers);
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
    LookUpAtPose(field, query, candidate, &lookups);
    const double cost_new = CostOfLookups(lookups, cutoff_sq);
    result.iterations = iteration + 1;
    if (!(cost_new < cost)) {
      lambda *= 10.0;
      if (lambda > 1e6) break;
      continue;
    }
    Eigen::Matrix3d H_new;
    Eigen::Vector3d b_new;
    int inliers_new = 0;
    NormalEquations(field, query, candidate, options.cutoff_m, lookups, &H_new, &b_new,
                    &inliers_new);
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
