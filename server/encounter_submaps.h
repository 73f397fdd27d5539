#pragma once
// Each trajectory's submaps for the scan encounters' searches (near, global and look back):
// KeyframeSubmap's 2 submap_half_width + 1 keyframes every submap_stride, drawn once when
// their keyframes are solved (at the estimates of the time), their references built when a
// search uses one (SubmapCache: the same bits as building it at once; most submaps of a large
// team are never searched).

#include <cstddef>
#include <map>
#include <memory>
#include <vector>

#include "common/scan_matching/scan_reference.h"
#include "common/solver/keys.h"
#include "server/encounter_source.h"
#include "server/keyframe_submap.h"
#include "server/scan_encounter_options.h"
#include "server/scan_encounter_state.h"
#include "server/submap_cache.h"

namespace anchormap {

class EncounterSubmaps {
 public:
  struct Submap {
    PoseKey center;
    SubmapDrawing drawing;
  };

  explicit EncounterSubmaps(const ScanEncounterOptions& options)
      : options_(options),
        references_(options.submap_cache, options.max_range_m, options.reference) {}

  // Draws every trajectory's submaps whose keyframes are all solved now.
  void Build(const GraphView& graph);
  // The submaps of `trajectory`, in order of their centres (an empty list made for one never
  // seen).
  std::vector<Submap>& Of(TrajectoryId trajectory) { return submaps_[trajectory]; }
  // The same, or null for a trajectory never seen.
  const std::vector<Submap>* Find(TrajectoryId trajectory) const;
  // The submap's reference, built now or taken from the cache (null without its record).
  std::shared_ptr<const ScanReference> Reference(const Submap& submap, const GraphView& graph);
  const SubmapCache& references() const { return references_; }

  // Snapshots: the drawings (scan_encounter_state.h); the references are not held.
  void ExportState(ScanEncounterState* s) const;
  void ImportState(const ScanEncounterState& s);

 private:
  ScanEncounterOptions options_;
  std::map<TrajectoryId, std::vector<Submap>> submaps_;
  SubmapCache references_;
};

}  // namespace anchormap
