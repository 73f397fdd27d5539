#pragma once
// Built submap references (ScanReference: likelihood grid, field, max-grid pyramid; a few
// MB each), kept for reuse under a memory budget. The scan-matching sources match many
// keyframes against the same submaps: consecutive keyframes of a robot share their loop
// candidates and their nearest submap of a teammate. Building each reference afresh cost
// ~12 % of the server's CPU at 100 robots; keeping every reference ever built grew the
// process to 4.5 GB. Here the least recently used ones are dropped beyond the budget and
// built again from their drawing when needed: a reference is a pure function of its
// drawing, so the matches, and the map, do not depend on the budget.
//
// A cached reference serves a new drawing of the same submap when the two hold the same
// keyframes at poses no further apart than reuse_m / reuse_rad (0: equal to the bit, the
// default; a one-scan submap is always drawn at the identity, so it is always reused). No
// caller's kept drawing moves today (a scan encounter's submap is drawn once; the loop
// closures keep one-scan references only), so no daemon flag sets them: at 100 robots x 180 s
// every rebuild was of a drawing evicted before, equal to the bit (docs/ARCHITECTURE.md,
// "Server cost at scale", front22).

#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <tuple>

#include "common/scan_matching/scan_reference.h"
#include "common/solver/keys.h"
#include "common/util/status.h"
#include "server/keyframe_submap.h"
#include "server/trajectory_table.h"

namespace anchormap {

struct SubmapCacheOptions {
  double budget_mb = 128.0;  // estimated bytes of the references held (one is always kept)
  double reuse_m = 0.0;      // keyframes moved at most this far since the reference was drawn
  double reuse_rad = 0.0;

  Status Validate() const;
};

struct SubmapCacheStats {
  int64_t hits = 0;
  int64_t builds = 0;     // references built (first use, redrawn, or after an eviction)
  int64_t evictions = 0;  // dropped for the budget
  int64_t held = 0;       // references held now
  int64_t bytes = 0;      // their estimated size
  int64_t peak_bytes = 0;

  std::string Summary(const std::string& name) const;
};

// The estimated memory of a reference: its grids' cells times the bytes each level keeps.
size_t ReferenceBytes(const ScanReference& reference);

class SubmapCache {
 public:
  SubmapCache(const SubmapCacheOptions& options, double max_range_m,
              const ScanReferenceOptions& reference)
      : options_(options), max_range_m_(max_range_m), reference_(reference) {}

  // The reference of `drawing` (a submap of `record`'s keyframes, `half_width` on each side
  // of its centre); nullptr when it holds no point.
  std::shared_ptr<const ScanReference> Get(const TrajectoryRecord& record,
                                           const SubmapDrawing& drawing, int half_width);

  // The reference of a drawing that will not be drawn with the same bits again (a wide loop
  // search's submaps, drawn at the estimates of the moment: 0 of 173 reused at 100 robots x
  // 60 s), built and not kept: keeping it would only evict references that are asked again.
  // Counted as a build.
  std::shared_ptr<const ScanReference> BuildUnkept(const TrajectoryRecord& record,
                                                   const SubmapDrawing& drawing);

  const SubmapCacheStats& stats() const { return stats_; }

 private:
  struct Entry {
    SubmapDrawing drawing;
    std::shared_ptr<const ScanReference> reference;
    size_t bytes = 0;
    uint64_t last_use = 0;
  };
  using EntryKey = std::tuple<int64_t, int32_t, int>;  // centre (trajectory, index), half width

  bool Reusable(const SubmapDrawing& cached, const SubmapDrawing& drawing) const;
  void Touch(const EntryKey& key, Entry* entry);
  void EvictBeyondBudget(const EntryKey& keep);

  SubmapCacheOptions options_;
  double max_range_m_;
  ScanReferenceOptions reference_;
  std::map<EntryKey, Entry> entries_;
  std::map<uint64_t, EntryKey> by_use_;  // least recently used first
  uint64_t tick_ = 0;
  SubmapCacheStats stats_;
};

}  // namespace anchormap
