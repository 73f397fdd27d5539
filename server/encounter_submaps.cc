#include "server/encounter_submaps.h"

#include <utility>

#include "common/solver/smoother.h"
#include "server/trajectory_table.h"

namespace anchormap {

void EncounterSubmaps::Build(const GraphView& graph) {
  for (const TrajectoryRecord& record : graph.table.records()) {
    std::vector<Submap>& submaps = submaps_[record.solver_id];
    for (;;) {
      const int center =
          options_.submap_half_width + static_cast<int>(submaps.size()) * options_.submap_stride;
      const PoseKey last{record.solver_id, center + options_.submap_half_width};
      if (last.index >= record.num_keyframes() || !graph.covariances->HasCovariance(last)) break;
      Submap submap;
      submap.center = PoseKey{record.solver_id, center};
      submap.drawing = DrawKeyframeSubmap(record, graph.smoother, submap.center,
                                          options_.submap_half_width, options_.max_range_m);
      submaps.push_back(std::move(submap));
    }
  }
}

const std::vector<EncounterSubmaps::Submap>* EncounterSubmaps::Find(TrajectoryId trajectory) const {
  const auto it = submaps_.find(trajectory);
  return it == submaps_.end() ? nullptr : &it->second;
}

std::shared_ptr<const ScanReference> EncounterSubmaps::Reference(const Submap& submap,
                                                                 const GraphView& graph) {
  const TrajectoryRecord* record = graph.table.FindBySolverId(submap.center.trajectory);
  if (record == nullptr) return nullptr;
  return references_.Get(*record, submap.drawing, options_.submap_half_width);
}

void EncounterSubmaps::ExportState(ScanEncounterState* s) const {
  for (const auto& [trajectory, submaps] : submaps_) {
    auto& out = s->submaps[trajectory];
    for (const Submap& submap : submaps) out.emplace_back(submap.center, submap.drawing);
  }
}

void EncounterSubmaps::ImportState(const ScanEncounterState& s) {
  submaps_.clear();
  for (const auto& [trajectory, submaps] : s.submaps) {
    std::vector<Submap>& out = submaps_[trajectory];
    for (const auto& [center, drawing] : submaps) out.push_back({center, drawing});
  }
}

}  // namespace anchormap
