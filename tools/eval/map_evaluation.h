#pragma once
// Puts the estimate and the references together: ATE / RPE per trajectory (each aligned on its
// own) and for the merged map (one alignment for the largest group of anchored trajectories),
// and the estimate the relations metric runs on. No file access here.

#include <string>

#include "common/util/status.h"
#include "tools/eval/eval_inputs.h"
#include "tools/eval/eval_report.h"
#include "tools/eval/relations.h"

namespace anchormap {

// Per-trajectory and merged errors. Trajectories of robots without reference poses are
// listed without errors; the merged row exists when the largest anchored group has matches.
AteReport EvaluateAgainstReferences(const MapEstimate& estimate, const ReferenceSet& references,
                                    double max_time_gap_s);

// The poses of robot `robot`'s trajectories ("" = every trajectory) merged in time order, each
// tagged with its frame: its group when anchored, a frame of its own otherwise. Fails when no
// trajectory matches.
Status BuildRelationsEstimate(const MapEstimate& estimate, const std::string& robot,
                              RelationsEstimate* relations_estimate);

}  // namespace anchormap
