#pragma once
// The smoother's incremental state (issue 13: a restored server continues exactly as the
// uninterrupted one): everything Update() and the estimates read beyond the graph itself.
// The graph (variables, factors, gauge priors, anchors, anchor groups) follows from the
// Add* calls in their order; a smoother given the same calls and then this state (Smoother::
// ImportState) holds bit for bit what the exporting one held: the linearisation points, R
// and d, delta and its correction, the pending variables and factors, the step policy's
// counters, the statistics. Not held: covariances memoised since the last Update() (each
// entry is one formula of R's blocks: recomputed the same) and work spaces. Plain values:
// the solver knows no format (server/smoother_state_codec.h writes them).

#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/solver/factor.h"
#include "common/solver/smoother.h"
#include "common/solver/sparse_r.h"

namespace anchormap {

struct SmootherState {
  struct Variable {
    Pose2 linearization;  // theta
    int position = -1;    // elimination position; -1 while pending
  };
  struct FactorState {
    bool active = true;  // false once removed (checked against the graph's own)
    bool in_r = false;   // its rows are in R, linearised at `at`
    std::array<Pose2, kMaxFactorKeys> at{};
  };
  std::vector<Variable> variables;   // by variable, in order of creation
  std::vector<FactorState> factors;  // by factor id, in order of creation
  std::vector<int64_t> pending_factors;
  std::vector<int> pending_variables;
  std::vector<uint8_t> grounded;  // by variable: in R for the incremental step
  std::vector<int> position_to_variable;
  std::vector<Eigen::Vector3d> delta;       // by position
  std::vector<Eigen::Vector3d> correction;  // by variable
  bool correction_converged = false;
  double last_chi2 = 0.0;
  double innovation = 0.0;
  // Kept-estimate mode: the factors that entered R since the last correction ran (the
  // skip test sums their gradient).
  std::vector<int64_t> uncorrected_factors;
  // correction_local_hops: the variables local corrections moved since the last gradient
  // pass, each with its value at that pass (in the order they were first moved); the
  // factors that pass counted which see them (sorted; the skip test adds their change);
  // and where in uncorrected_factors the factors since the last local correction begin
  // (its next region's seeds).
  struct PassValue {
    int variable = -1;
    Pose2 value;
  };
  std::vector<PassValue> local_pass_values;
  std::vector<int64_t> local_moved_factors;
  int64_t local_seeds_from = 0;
  SparseR::State r;
  bool merge_pending = false;
  std::vector<int> merge_variables;
  double tolerance = 0.0;
  int updates_since_batch = 0;
  int updates_since_drift_check = 0;
  int64_t nonzeros_after_batch = 0;
  SmootherStats stats;
  // The reduced graph's aliases follow from the Add* calls (AddAlias, AddPose of borrowed
  // nodes, measurements inside one node) as the variables do; their counts are here to be
  // checked against the graph's own.
  int64_t aliases = 0;
  int64_t measurements_inside_nodes = 0;
};

}  // namespace anchormap
