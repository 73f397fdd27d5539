#pragma once
// The covariance of a match from the distribution of its score (Olson, ICRA 2009, section
// III.C: the weighted second moment of the likelihood over the search volume). The score is the
// log-likelihood of the query under a Gaussian point-to-surface model with standard deviation
// point_sigma_m, truncated at cutoff_m (outliers): log p(xi) = -cost(xi) / (2 sigma^2),
// cost as AnchoredCost (pose_refinement.h). Instead of the search lattice, whose cells (5 cm,
// 0.1-0.3 degree) are coarser than a good match's uncertainty, the distribution is sampled on a 5 x
// 5 x 5 lattice along the principal axes of the Gauss-Newton covariance (steps of 1.5 standard
// deviations to +-3, a window prior bounding it): where the likelihood is Gaussian the moment
// reproduces it, where it is not (a corridor, a truncation edge, a second nearby optimum) the
// moment follows the samples. Directions the geometry leaves unconstrained (DegeneracyFiltered) are
// not sampled for their spread (the samples there follow the walls' noise): they get the window
// prior's variance. The result is symmetrised and a floor is added, so it is always SPD.

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/scan_matching/point_cloud.h"
#include "common/scan_matching/reference_field.h"

namespace anchormap {

struct ScoreCovarianceOptions {
  double point_sigma_m = 0.03;
  double cutoff_m = 0.1;
  // The search window, as a Gaussian prior: no axis is reported wider than this.
  double window_sigma_xy_m = 0.5;
  double window_sigma_theta_rad = 0.3;
  // Added to the moment: the resolution of the interpolated field and of the sampling.
  double floor_sigma_xy_m = 0.0005;
  double floor_sigma_theta_rad = 0.0001;
};

// The Hessian with its degenerate directions set to zero (unconstrained: the window prior
// bounds them): those with less than 2 % of the best direction's information, the heading
// scaled by the query's RMS range (Zhang, Kaess and Singh, ICRA 2016). Pass the result to
// both covariance functions below.
Eigen::Matrix3d DegeneracyFiltered(const Eigen::Matrix3d& hessian, const PointCloud& query);

// The covariance of T_reference_query around `pose` (a refined match); `hessian` is the
// RefinementResult's after DegeneracyFiltered.
Eigen::Matrix3d ScoreDistributionCovariance(const ReferenceField& field, const PointCloud& query,
                                            const Pose2& pose, const Eigen::Matrix3d& hessian,
                                            const ScoreCovarianceOptions& options);

// The Laplace approximation of the same distribution: (H / sigma^2 + window prior)^-1 plus the
// floor, with `hessian` after DegeneracyFiltered (its zeroed directions get the window prior's
// variance, so a corridor's axis is as wide as the search window). ScoreDistributionCovariance's
// sampling frame without its 125 cost evaluations: on a Gaussian likelihood the two agree; where
// the likelihood is flatter than its curvature at the optimum (truncation, a nearby second
// optimum), this one is tighter.
Eigen::Matrix3d LaplaceCovariance(const Eigen::Matrix3d& hessian,
                                  const ScoreCovarianceOptions& options);

// The reference is a scan too, with its own noise: a reference point displaced by delta moves
// the surface under every query point matched to its segments (weight 1 - t or t along the
// segment), and so moves the estimate. With sigma the noise of one point along the surface
// normal, the estimate's error from the reference is sigma^2 H^+ (sum_v b_v b_v^T) H^+, where
// b_v = sum_j w_jv a_j over the query points j matched near reference point v (signed by v's
// own normal), a_j the gradient of point j's normal residual, and H^+ the pseudo-inverse of
// the filtered Gauss-Newton Hessian (error propagation through the normal equations). The
// residuals see the reference's noise only partly (interpolated between two points: variance
// ((1 - t)^2 + t^2) sigma^2), which `interpolation_gain` reports for the variance estimate.
struct ReferenceNoiseTerms {
  Eigen::Matrix3d b_outer = Eigen::Matrix3d::Zero();  // sum_v b_v b_v^T
  double interpolation_gain = 1.0;  // mean over matched query points of (1 - t)^2 + t^2
  int matched = 0;
};

ReferenceNoiseTerms ComputeReferenceNoiseTerms(const ReferenceField& field, const PointCloud& query,
                                               const Pose2& pose, double cutoff_m);

// sigma^2 H^+ B H^+ (H the filtered Hessian, H^+ its pseudo-inverse: degenerate directions
// get nothing here, the score distribution's window prior bounds them).
Eigen::Matrix3d ReferenceNoiseCovariance(const ReferenceNoiseTerms& terms,
                                         const Eigen::Matrix3d& hessian, double point_sigma_m,
                                         const ScoreCovarianceOptions& options);

}  // namespace anchormap
