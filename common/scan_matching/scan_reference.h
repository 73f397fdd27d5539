#pragma once
// Everything a match needs from its reference, built once and shared by every query matched
// against it: the reference field (vectors to the nearest surface, for refinement, covariance
// and overlap), the likelihood grid (the score; the pyramid's level 0) and its max-grid
// pyramid's bounds (branch and bound), as floats or bytes, each built when first asked for.
// Building costs O(reference points x (max distance / resolution)^2) plus O(levels x cells).

#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "common/scan_matching/byte_max_grids.h"
#include "common/scan_matching/likelihood_grid.h"
#include "common/scan_matching/max_grid_pyramid.h"
#include "common/scan_matching/point_cloud.h"
#include "common/scan_matching/reference_field.h"
#include "common/util/status.h"

namespace anchormap {

struct ScanReferenceOptions {
  double resolution_m = 0.05;
  // Blur of the likelihood grid (one search cell plus sensor noise): a pose one cell off
  // still scores exp(-1/2) per point on a wall, so the lattice search sees a smooth peak.
  double likelihood_sigma_m = 0.05;
  // Consecutive returns at most this far apart are one wall (ReferenceField).
  double max_join_gap_m = 0.5;
  // Max-grid levels: blocks of up to 2^(levels-1) cells. 7 levels = 3.2 m blocks at 5 cm.
  int num_levels = 7;

  Status Validate() const;
};

class ScanReference {
 public:
  // `scans`: each scan's points in the reference frame, in beam order (e.g.
  // TransformPointCloud(ScanToPointCloud(scan), T_reference_body)). Options must be valid.
  ScanReference(const std::vector<PointCloud>& scans, const ScanReferenceOptions& options);
  // The same reference from the scans' surfaces (MakeScanSurface with options.max_join_gap_m).
  ScanReference(const std::vector<std::shared_ptr<const ScanSurface>>& surfaces,
                const ScanReferenceOptions& options);

  const ScanReferenceOptions& options() const { return options_; }
  const ReferenceField& field() const { return field_; }
  // Every level of the max-grid pyramid, the levels above 0 built on the first call (once,
  // though several match workers search one submap at a time): only searches bounded on the
  // floats ask for them (the loop closures' wide searches, whose budget counts their nodes).
  const MaxGridPyramid& pyramid() const;
  // The pyramid's level 0 (the likelihood grid; its levels above may not be built yet): what a
  // search bounded on byte_bounds() reads.
  const MaxGridPyramid& base() const { return pyramid_; }
  const GridGeometry& geometry() const { return field_.geometry(); }
  bool empty() const { return field_.num_points() == 0; }
  // The pyramid's levels as bytes for the searches' inner nodes (byte_max_grids.h), built from
  // level 0 on the first call; null when the pyramid's sums are not exact.
  const ByteMaxGrids* byte_bounds() const;
  // The same likelihood grid (cells and values), exactly: a reference built again from the
  // same drawing equals the first.
  bool SameLikelihood(const ScanReference& other) const {
    return pyramid_.SameBase(other.pyramid_);
  }

 private:
  static ReferenceFieldOptions FieldOptions(const ScanReferenceOptions& options);

  ScanReferenceOptions options_;
  ReferenceField field_;
  // Level 0 at construction, the levels above on the first pyramid() (Lazy::levels).
  mutable MaxGridPyramid pyramid_;
  struct Lazy {
    std::once_flag levels;
    std::once_flag bytes;
    std::unique_ptr<const ByteMaxGrids> grids;
  };
  std::unique_ptr<Lazy> lazy_ = std::make_unique<Lazy>();
};

}  // namespace anchormap
