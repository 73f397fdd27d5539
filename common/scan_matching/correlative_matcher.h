#pragma once
// The correlative scan matcher (Olson, "Real-time correlative scan matching", ICRA 2009) on one
// ScanReference (the global search, global_search.h, shares all but the window):
//   1. the query is scored on a lattice of poses (x, y, theta) by its mean likelihood, and the
//      best lattice pose is found by branch and bound over the precomputed max-grids (coarse
//      to fine, exact: the best lattice score);
//   2. the pose is refined continuously (point-to-surface Gauss-Newton, pose_refinement.h);
//   3. the covariance comes from the score distribution around it (score_covariance.h);
//   4. the overlap is the fraction of query points within overlap_distance_m of the surface.
// MatchLocal searches a window around a guess (odometry, a predicted loop closure). It returns
// nullopt when no lattice pose scores above min_score. Deterministic.

#include <cstdint>
#include <optional>
#include <string>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/scan_matching/lattice_search.h"
#include "common/scan_matching/point_cloud.h"
#include "common/scan_matching/pose_refinement.h"
#include "common/scan_matching/scan_reference.h"
#include "common/util/status.h"

namespace anchormap {

// How a match's covariance spreads the query's noise (the reference's is propagated either way).
enum class MatchCovariance {
  // The score distribution's moment on 125 samples (ScoreDistributionCovariance): follows a
  // likelihood that is not Gaussian (a corridor, a truncation edge, a second optimum nearby).
  kScoreDistribution,
  // The Laplace approximation at the refined pose (LaplaceCovariance): no cost evaluations,
  // Gaussian by construction; degenerate directions get the window prior as above.
  kLaplace,
};

struct MatchOptions {
  // No match below this lattice score (mean likelihood of the query's points, in [0, 1]).
  double min_score = 0.3;
  // Standard deviation of one point's distance to the reference surface (range noise of both
  // scans, surface roughness): the noise model of the refinement and of the covariance.
  double point_sigma_m = 0.03;
  // A query point "lands near" the reference when this close to its surface.
  double overlap_distance_m = 0.1;
  bool refine = true;
  // False: `covariance` is left at the identity (the score distribution is most of a match's
  // cost); AddCovariance on the result gives it later, identically.
  bool covariance = true;
  MatchCovariance covariance_model = MatchCovariance::kScoreDistribution;
  // A result below either bar keeps the identity as its covariance: the caller that set them
  // discards such a match unused (a fifth of the servers' matches; the covariance is most of
  // a local match's cost). 0: every result gets its covariance.
  double covariance_min_score = 0.0;
  double covariance_min_overlap = 0.0;

  Status Validate() const;
};

struct LocalMatchOptions {
  double linear_window_m = 0.4;     // +- on x and y around the guess
  double angular_window_rad = 0.2;  // +- around the guess's heading
  MatchOptions match;

  Status Validate() const;
};

struct MatchResult {
  Pose2 pose;            // T_reference_query
  double score = 0.0;    // of the best lattice pose
  double overlap = 0.0;  // at `pose`
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
  Pose2 lattice_pose;  // before refinement
  LatticeSearchStats search;
  // Where the pose was found: FinishMatch(reference, query, window, lattice, options) gives
  // this result again (e.g. with the covariance, when the search skipped it).
  SearchWindow window;
  LatticePose lattice;
  // The refinement that gave `pose` (its Hessian, inliers and residual variance are the
  // covariance's input): AddCovariance needs no second refinement.
  RefinementResult refinement;
};

// The lattice bar (MatchOptions::min_score) at which a search returns exactly the matches a
// caller keeping only scores >= `acceptance` keeps, the same pose and score: the largest double
// below `acceptance` (branch and bound keeps scores above its bar), or `bar` when that is higher.
// Below it a match is dropped unused, so its search may prune there and skip its refinement.
double LatticeBarFor(double acceptance, double bar);

// Matches `query` (points in its body frame) around T_reference_query `guess`. Options must be
// valid (exceptions are for bugs).
std::optional<MatchResult> MatchLocal(const ScanReference& reference, const PointCloud& query,
                                      const Pose2& guess, const LocalMatchOptions& options);

// MatchLocal's lattice search alone: the score of the pose it would refine (nullopt where it
// finds none above options.match.min_score), without the refinement, overlap and covariance
// (a choice among references by their scores needs no more).
std::optional<double> LocalLatticeScore(const ScanReference& reference, const PointCloud& query,
                                        const Pose2& guess, const LocalMatchOptions& options);

// MatchLocal without the lattice search, for a guess already within the refinement's reach
// (a keyframe predicted from its predecessor's own match): the refinement starts at `guess`,
// the score is the likelihood grid's mean over the query's points at the refined pose (the
// lattice's measure at that pose), the overlap and covariance are FinishMatch's. The result's
// window is `guess` alone. nullopt when the reference or the query is empty.
std::optional<MatchResult> RefineFromGuess(const ScanReference& reference, const PointCloud& query,
                                           const Pose2& guess, const MatchOptions& options);

// The likelihood grid's mean over `query` at T_reference_query `pose` (a point's cell's value,
// 0 outside the grid): a lattice pose's score, at any pose.
double MeanLikelihood(const ScanReference& reference, const PointCloud& query, const Pose2& pose);

// Steps 1-4 on a given window (MatchLocal's and GlobalSearch's common part); `bytes`: the
// lattice search's inner bounds on reference.byte_bounds(); `centre_first`: the window's centre
// scored first (BranchAndBound; the same match either way).
std::optional<MatchResult> SearchWindowAndFinish(const ScanReference& reference,
                                                 const PointCloud& query,
                                                 const SearchWindow& window,
                                                 const MatchOptions& options, bool bytes = false,
                                                 bool centre_first = false);

// Steps 2-4 for a lattice pose found by a search (exposed for tests and benchmarks).
MatchResult FinishMatch(const ScanReference& reference, const PointCloud& query,
                        const SearchWindow& window, const LatticePose& lattice,
                        const MatchOptions& options);

// Step 3 for a result FinishMatch finished with options.covariance false: the covariance it
// gives with options.covariance true (the same bits, from result->refinement: a keyframe's
// covariance was a second refinement of the same lattice pose). Needs the same reference,
// query and other options.
void AddCovariance(const ScanReference& reference, const PointCloud& query,
                   const MatchOptions& options, MatchResult* result);

// The fraction of `query` at T_reference_query `pose` within `distance_m` of the surface.
double Overlap(const ReferenceField& field, const PointCloud& query, const Pose2& pose,
               double distance_m);

}  // namespace anchormap
