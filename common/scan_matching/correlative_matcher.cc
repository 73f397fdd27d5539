#include "common/scan_matching/correlative_matcher.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "common/scan_matching/pose_refinement.h"
#include "common/scan_matching/score_covariance.h"

namespace anchormap {

namespace {

constexpr int kMinInliersForVariance = 20;

template <typename Options>
void Require(const Options& options) {
  if (const Status valid = options.Validate(); !valid.ok()) {
    throw std::invalid_argument("scan matching: " + valid.message());
  }
}

}  // namespace

Status MatchOptions::Validate() const {
  if (!(min_score >= 0.0 && min_score < 1.0)) return Status::Error("min_score must be in [0, 1)");
  if (!(point_sigma_m > 0.0) || !std::isfinite(point_sigma_m)) {
    return Status::Error("point_sigma_m must be > 0");
  }
  if (!(overlap_distance_m > 0.0) || !std::isfinite(overlap_distance_m)) {
    return Status::Error("overlap_distance_m must be > 0");
  }
  return Status::Ok();
}

Status LocalMatchOptions::Validate() const {
  if (!(linear_window_m >= 0.0 && linear_window_m <= 100.0)) {
    return Status::Error("linear_window_m must be in [0, 100]");
  }
  if (!(angular_window_rad >= 0.0 && angular_window_rad <= kPi)) {
    return Status::Error("angular_window_rad must be in [0, pi]");
  }
  return match.Validate();
}

double LatticeBarFor(double acceptance, double bar) {
  return std::max(bar, std::nextafter(acceptance, -std::numeric_limits<double>::infinity()));
}

double Overlap(const ReferenceField& field, const PointCloud& query, const Pose2& pose,
               double distance_m) {
  if (query.empty()) return 0.0;
  const Eigen::Matrix2d R = pose.rotation();
  const Eigen::Vector2d t = pose.translation();
  const GridGeometry& g = field.geometry();
  int near = 0;
  for (const Eigen::Vector2d& p : query) {
    const Eigen::Vector2d q = R * p + t;
    const Eigen::Vector2i c = g.CellOf(q);
    Eigen::Vector2d v;
    // The cell centre's vector, moved to the point: exact for the nearest surface point.
    if (field.NearestVector(c.x(), c.y(), &v) &&
        (g.CellCentre(c.x(), c.y()) + v - q).norm() <= distance_m) {
      ++near;
    }
  }
  return static_cast<double>(near) / static_cast<double>(query.size());
}

namespace {

// Step 1: the best lattice pose in the window (BranchAndBound).
std::optional<LatticePose> SearchLattice(const ScanReference& reference, const PointCloud& query,
                                         const SearchWindow& window, double min_score, bool bytes,
                                         bool centre_first, LatticeSearchStats* stats) {
  const DiscretisedQuery discretised(query, window, reference.geometry());
  // On the bytes only level 0 of the floats is read: their levels above are not built for it.
  const ByteMaxGrids* byte_bounds =
      bytes && ByteBoundsApply(reference.base(), discretised) ? reference.byte_bounds() : nullptr;
  const MaxGridPyramid& grids = byte_bounds != nullptr ? reference.base() : reference.pyramid();
  return BranchAndBound(grids, discretised, window, min_score, stats, byte_bounds, centre_first);
}

// MatchLocal's window around `guess`.
SearchWindow LocalWindow(const ScanReference& reference, const PointCloud& query,
                         const Pose2& guess, const LocalMatchOptions& options) {
  const double resolution = reference.geometry().resolution;
  SearchWindow window;
  window.center = guess;
  window.angle_step_rad = AngleStepForRange(resolution, MaxPointRange(query));
  window.half_angles =
      static_cast<int>(std::ceil(options.angular_window_rad / window.angle_step_rad));
  window.half_cells_x = static_cast<int>(std::ceil(options.linear_window_m / resolution));
  window.half_cells_y = window.half_cells_x;
  return window;
}

}  // namespace

std::optional<MatchResult> SearchWindowAndFinish(const ScanReference& reference,
                                                 const PointCloud& query,
                                                 const SearchWindow& window,
                                                 const MatchOptions& options, bool bytes,
                                                 bool centre_first) {
  if (reference.empty() || query.empty()) return std::nullopt;
  LatticeSearchStats stats;
  const std::optional<LatticePose> best =
      SearchLattice(reference, query, window, options.min_score, bytes, centre_first, &stats);
  if (!best) return std::nullopt;
  MatchResult result = FinishMatch(reference, query, window, *best, options);
  result.search = stats;
  return result;
}

namespace {

// The refinement's cut-off: three point sigmas, at least two cells, within the field's reach.
double RefinementCutoff(const ScanReference& reference, const MatchOptions& options) {
  return std::min(std::max(3.0 * options.point_sigma_m, 2.0 * reference.geometry().resolution),
                  reference.field().options().max_distance_m);
}

// The refinement from `start` (its Hessian at `start` alone when options.refine is off).
RefinementResult RefineMatch(const ScanReference& reference, const PointCloud& query,
                             const Pose2& start, const MatchOptions& options) {
  RefinementOptions refine;
  refine.cutoff_m = RefinementCutoff(reference, options);
  if (!options.refine) refine.max_iterations = 0;
  return RefinePose(reference.field(), query, start, refine);
}

}  // namespace

MatchResult FinishMatch(const ScanReference& reference, const PointCloud& query,
                        const SearchWindow& window, const LatticePose& lattice,
                        const MatchOptions& options) {
  MatchResult result;
  result.window = window;
  result.lattice = lattice;
  result.score = lattice.score;
  result.lattice_pose = LatticeToPose(window, reference.geometry().resolution, lattice);
  result.refinement = RefineMatch(reference, query, result.lattice_pose, options);
  result.pose = result.refinement.pose;
  result.overlap = Overlap(reference.field(), query, result.pose, options.overlap_distance_m);
  if (options.covariance) AddCovariance(reference, query, options, &result);
  return result;
}

void AddCovariance(const ScanReference& reference, const PointCloud& query,
                   const MatchOptions& options, MatchResult* result) {
  if (result->score < options.covariance_min_score ||
      result->overlap < options.covariance_min_overlap) {
    return;
  }
  const RefinementResult& refined = result->refinement;
  const double resolution = reference.geometry().resolution;
  const double cutoff_m = RefinementCutoff(reference, options);
  ScoreCovarianceOptions covariance;
  // The noise of one point along the surface normal, estimated from the residuals (the
  // a-posteriori variance factor of least squares), so that the covariance follows the sensor
  // and the place, not a setting: a residual carries the query point's noise and the
  // reference's, interpolated ((1 - t)^2 + t^2 of it). The option is the fallback for too few
  // inliers and the refinement's cut-off scale.
  const ReferenceNoiseTerms reference_noise =
      ComputeReferenceNoiseTerms(reference.field(), query, result->pose, cutoff_m);
  covariance.point_sigma_m = refined.inliers >= kMinInliersForVariance
                                 ? std::sqrt(std::max(refined.residual_variance, 1e-8) /
                                             (1.0 + reference_noise.interpolation_gain))
                                 : options.point_sigma_m;
  if (!options.refine) {
    // The lattice's own resolution bounds the estimate: a uniform error over one cell.
    covariance.floor_sigma_xy_m = resolution / std::sqrt(12.0);
    covariance.floor_sigma_theta_rad = result->window.angle_step_rad / std::sqrt(12.0);
  }
  // The query's noise through the score distribution, the reference's by propagation.
  const Eigen::Matrix3d hessian = DegeneracyFiltered(refined.hessian, query);
  const Eigen::Matrix3d query_noise =
      options.covariance_model == MatchCovariance::kLaplace
          ? LaplaceCovariance(hessian, covariance)
          : ScoreDistributionCovariance(reference.field(), query, result->pose, hessian,
                                        covariance);
  result->covariance = query_noise + ReferenceNoiseCovariance(reference_noise, hessian,
                                                              covariance.point_sigma_m, covariance);
}

std::optional<MatchResult> MatchLocal(const ScanReference& reference, const PointCloud& query,
                                      const Pose2& guess, const LocalMatchOptions& options) {
  Require(options);
  // The guess first: usually near the best, its score prunes most of the window at once
  // (fr079-3s's agents 1.06-1.12 -> 1.00-1.02 ms/scan). Inner nodes on the bytes: the same
  // match, and a reference searched only locally never builds the float levels.
  return SearchWindowAndFinish(reference, query, LocalWindow(reference, query, guess, options),
                               options.match, /*bytes=*/true, /*centre_first=*/true);
}

double MeanLikelihood(const ScanReference& reference, const PointCloud& query, const Pose2& pose) {
  if (query.empty()) return 0.0;
  const Eigen::Matrix2d R = pose.rotation();
  const Eigen::Vector2d t = pose.translation();
  const GridGeometry& g = reference.geometry();
  const MaxGridPyramid& grid = reference.base();
  double sum = 0.0;
  for (const Eigen::Vector2d& p : query) {
    const Eigen::Vector2i c = g.CellOf(R * p + t);
    sum += grid.Value(0, c.x(), c.y());
  }
  return sum / static_cast<double>(query.size());
}

std::optional<MatchResult> RefineFromGuess(const ScanReference& reference, const PointCloud& query,
                                           const Pose2& guess, const MatchOptions& options) {
  if (reference.empty() || query.empty()) return std::nullopt;
  MatchResult result;
  result.window.center = guess;
  result.window.angle_step_rad =
      AngleStepForRange(reference.geometry().resolution, MaxPointRange(query));
  result.lattice_pose = guess;
  result.refinement = RefineMatch(reference, query, guess, options);
  result.pose = result.refinement.pose;
  result.score = MeanLikelihood(reference, query, result.pose);
  result.lattice = LatticePose{0, 0, 0, result.score};
  result.overlap = Overlap(reference.field(), query, result.pose, options.overlap_distance_m);
  if (options.covariance) AddCovariance(reference, query, options, &result);
  return result;
}

std::optional<double> LocalLatticeScore(const ScanReference& reference, const PointCloud& query,
                                        const Pose2& guess, const LocalMatchOptions& options) {
  Require(options);
  if (reference.empty() || query.empty()) return std::nullopt;
  const std::optional<LatticePose> best =
      SearchLattice(reference, query, LocalWindow(reference, query, guess, options),
                    options.match.min_score, /*bytes=*/true, /*centre_first=*/true, nullptr);
  if (!best) return std::nullopt;
  return best->score;
}

}  // namespace anchormap
