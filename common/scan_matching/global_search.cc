#include "common/scan_matching/global_search.h"

#include <cmath>
#include <stdexcept>

#include "common/geometry/angle.h"

namespace anchormap {

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
  // Its inner nodes on the bytes: the same match from a quarter of the bounds' memory, summed
  // in integers (the global searches were the largest share of a replay's CPU).
  return SearchWindowAndFinish(reference, query, GlobalSearchWindow(reference, query),
                               options.match, /*bytes=*/true);
}

}  // namespace anchormap
