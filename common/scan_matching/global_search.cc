#include "common/scan_matching/global_search.h"

#include <cmath>
#include <stdexcept>

#include "common/geometry/angle.h"

namespace anchormap {

Status GlobalSearchOptions::Validate() const {
  if (!(query_spacing_m >= 0.0) || !std::isfinite(query_spacing_m)) {
    return Status::Error("query_spacing_m must be finite and >= 0");
  }
  return match.Validate();
}

PointCloud ThinOutQuery(const PointCloud& query, double spacing_m) {
  if (!(spacing_m > 0.0)) return query;
  PointCloud kept;
  kept.reserve(query.size());
  const double spacing_sq = spacing_m * spacing_m;
  for (const Eigen::Vector2d& p : query) {
    if (kept.empty() || (p - kept.back()).squaredNorm() >= spacing_sq) kept.push_back(p);
  }
  return kept;
}

SearchWindow GlobalSearchWindow(const ScanReference& reference, const PointCloud& query) {
  const GridGeometry& g = reference.geometry();
  SearchWindow window;
  const Eigen::Vector2d centre = g.origin + 0.5 * g.resolution * Eigen::Vector2d(g.width, g.height);
  window.center = Pose2(centre.x(), centre.y(), 0.0);
  window.angle_step_rad = AngleStepForRange(g.resolution, MaxPointRange(query));
  // Headings k * step for |k| <= half cover (-pi, pi]; the two ends may coincide.
  window.half_angles = static_cast<int>(std::ceil(kPi / window.angle_step_rad));
  window.half_cells_x = (g.width + 1) / 2;
  window.half_cells_y = (g.height + 1) / 2;
  return window;
}

std::optional<MatchResult> GlobalSearch(const ScanReference& reference, const PointCloud& query,
                                        const GlobalSearchOptions& options) {
  if (const Status valid = options.Validate(); !valid.ok()) {
    throw std::invalid_argument("GlobalSearch: " + valid.message());
  }
  if (reference.empty() || query.empty()) return std::nullopt;
  const SearchWindow window = GlobalSearchWindow(reference, query);
  if (!(options.query_spacing_m > 0.0)) {
    return SearchWindowAndFinish(reference, query, window, options.match);
  }
  const PointCloud thin = ThinOutQuery(query, options.query_spacing_m);
  const DiscretisedQuery discretised(thin, window, reference.geometry());
  LatticeSearchStats stats;
  const std::optional<LatticePose> best =
      BranchAndBound(reference.pyramid(), discretised, window, options.match.min_score, &stats);
  if (!best) return std::nullopt;
  MatchResult result = FinishMatch(reference, query, window, *best, options.match);
  result.search = stats;
  return result;
}

}  // namespace anchormap
