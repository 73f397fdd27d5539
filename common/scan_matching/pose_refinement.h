#pragma once
// Continuous refinement of a lattice match: Gauss-Newton on the point-to-surface residuals of
// the reference field, bilinearly interpolated (exact near straight walls, so this is
// point-to-line ICP without a correspondence search). Points farther than a cut-off from the
// surface are left out (a truncated quadratic: the robust kernel of the likelihood model).
// The lattice search leaves an error of up to half a cell and half an angle step; this removes
// it (figures in docs/ARCHITECTURE.md, "Scan matching").

#include <vector>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/scan_matching/point_cloud.h"
#include "common/scan_matching/reference_field.h"

namespace anchormap {

struct RefinementOptions {
  double cutoff_m = 0.1;  // residuals longer than this are outliers
  int max_iterations = 30;
  double min_step = 1e-6;  // stop when the update's norm (m, rad) is below
};

struct RefinementResult {
  Pose2 pose;
  // Sum over inlier points of A^T A, A = d(residual)/d(x, y, theta) at `pose` (the Gauss-
  // Newton Hessian of the squared residuals, without the noise variance).
  Eigen::Matrix3d hessian = Eigen::Matrix3d::Zero();
  int inliers = 0;
  // Sum of the inliers' squared residuals / (inliers - 3): the a-posteriori variance of one
  // point's distance to the surface (0 with fewer than 4 inliers).
  double residual_variance = 0.0;
  int iterations = 0;
};

// Refines T_reference_query from `initial`. Returns `initial` unchanged (with its Hessian)
// when no step lowers the truncated cost.
RefinementResult RefinePose(const ReferenceField& field, const PointCloud& query,
                            const Pose2& initial, const RefinementOptions& options);

// The truncated cost sum_j min(|v_j|^2, cutoff^2) of the query at `pose` (points without an
// interpolated vector count cutoff^2), and optionally the number of inliers.
double TruncatedCost(const ReferenceField& field, const PointCloud& query, const Pose2& pose,
                     double cutoff_m, int* inliers = nullptr);

// The truncated cost around a match, for sampling its score distribution: a point uses its
// residual from the field where it has one, else, if it was an inlier at `anchor`, its
// residual to the surface it matched there (the line through it along the wall, or the lone
// return), so that a point sliding past the end of the reference's view of a wall (the end of
// the reference's range, not of the wall) does not count as a mismatch; other points cost
// cutoff^2 wherever they land.
class AnchoredCost {
 public:
  AnchoredCost(const ReferenceField& field, const PointCloud& query, const Pose2& anchor,
               double cutoff_m);
  double operator()(const Pose2& pose) const;
  // operator() at each of `poses`, the same bits, taken point by point: one point's lookups
  // under every pose at once (a few cells of the field, read from L1) instead of every point's
  // under one pose (a sweep over the field per pose). Each pose's sum still adds its points in
  // query order.
  std::vector<double> operator()(const std::vector<Pose2>& poses) const;

 private:
  struct Association {
    bool inlier = false;
    bool has_normal = false;
    Eigen::Vector2d surface{0.0, 0.0};
    Eigen::Vector2d normal{0.0, 0.0};
  };
  const ReferenceField& field_;
  const PointCloud& query_;
  double cutoff_sq_;
  // Point j's share of the cost at lookup `i` of `at` (a lookup of that point).
  double PointCost(const ReferenceField::Lookups& at, size_t i, const Association& a) const;

  std::vector<Association> associations_;
  // The points of the pose being costed and the field's answers (scratch: one cost at a time).
  mutable ReferenceField::Lookups lookups_;
};

}  // namespace anchormap
