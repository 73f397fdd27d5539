#pragma once
// The direction along which a match's score stays flat (a corridor's axis), found from the
// score's own shape (the likelihood of the query's points on walls, shifted). Along a featureless
// corridor the likelihood score is a ridge: shifted along it the query's points stay on the walls,
// so the lattice optimum lies anywhere on the ridge, often on the search window's edge (ACES:
// single-scan corrections of 0.4 m flipping sign from one scan to the next), while the refinement's
// residuals still claim millimetres along it. The score says so: shifted by the window's reach
// along the ridge it keeps nearly all of its value, while in every other direction points fall off
// the walls within a few centimetres.
//
// Only the query's points on the reference's walls count (joined returns, not lone ones): far
// along a corridor the beams meet its walls at a grazing angle, farther apart than a join, and
// such lone returns repeat the reference scan's own beam pattern: a query taken where the
// reference was scores them best there, which holds the match back at the reference's pose
// (ACES: 4.7 m of odometry matched as 0.7 m) without saying anything about the corridor.

#include <optional>
#include <vector>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/scan_matching/point_cloud.h"
#include "common/scan_matching/scan_reference.h"
#include "common/util/status.h"

namespace anchormap {

struct FlatDirectionOptions {
  // The shift tried both ways along each direction (the local search window's half-width).
  double reach_m = 0.4;
  // Flat: shifted by reach_m both ways, the score keeps at least this fraction of its value
  // at the pose (so fewer than about 1 - ratio of the points constrain the direction). A plain
  // simulated corridor keeps 0.99, rooms 0.4-0.7; ACES's corridors 0.9-1, FR079 never 0.9.
  // Neither 0.9 nor 0.95 keeps every ACES split joined (docs/ARCHITECTURE.md, "Scan matching").
  double min_score_ratio = 0.9;
  // Directions tried over half a turn, then around the best one at half, a quarter and an
  // eighth of the step (10, 5, 2.5, 1.25 degrees: off a corridor's axis by a, a shift of
  // reach_m moves the points reach_m * sin(a) across its walls).
  int directions = 18;

  Status Validate() const;
};

struct FlatDirection {
  Eigen::Vector2d axis{1.0, 0.0};  // unit vector in the reference frame
  double score_ratio = 0.0;        // the smaller of the two shifted scores over the pose's
};

// A query point on a reference wall at the match: where it lies (reference frame), its foot on
// the wall and the wall's normal.
struct WallPoint {
  Eigen::Vector2d point;
  Eigen::Vector2d foot;
  Eigen::Vector2d normal;
};

// The query's points (body frame) on the reference's walls at T_reference_query `pose`: within
// the field's reach of a segment of joined returns (not a lone return).
std::vector<WallPoint> PointsOnWalls(const ReferenceField& field, const PointCloud& query,
                                     const Pose2& pose);

// The mean likelihood exp(-d^2 / 2 sigma^2) of the wall points moved by `shift`, d the distance
// to the nearest reference surface, or to the point's own wall's line where the reference saw
// no surface near it (past the end of its view: the corridor goes on beyond what the reference
// scans saw, and a point sliding off their view is no evidence against the shift).
double ShiftedWallScore(const ReferenceField& field, const std::vector<WallPoint>& points,
                        const Eigen::Vector2d& shift, double sigma_m);
// ShiftedWallScore when that is above `floor` (the same bits); otherwise a value at most
// `floor` (the summing stops once the points left cannot lift the mean above it).
double ShiftedWallScoreAbove(const ReferenceField& field, const std::vector<WallPoint>& points,
                             const Eigen::Vector2d& shift, double sigma_m, double floor);

// The most flat direction through `pose` (a refined match) for the query's points on walls, and
// its score ratio; nullopt when even that one is not flat (min_score_ratio), or fewer than 10
// points lie on walls. Options must be valid.
std::optional<FlatDirection> FindFlatDirection(const ScanReference& reference,
                                               const PointCloud& query, const Pose2& pose,
                                               const FlatDirectionOptions& options);

// The same search, returning the most flat direction whatever its ratio (for tests and
// diagnostics); nullopt only when fewer than 10 points lie on walls or they score nothing.
std::optional<FlatDirection> MostFlatDirection(const ScanReference& reference,
                                               const PointCloud& query, const Pose2& pose,
                                               const FlatDirectionOptions& options);

}  // namespace anchormap
