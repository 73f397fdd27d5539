#pragma once
// The smoother's step policy as pure functions of its statistics: which kind of step an
// update runs, whether a batch step iterates, and what drift leads to. No state here;
// the smoother keeps the counters (smoother_update.cc).

#include <cstdint>

#include "common/solver/smoother_options.h"

namespace anchormap {

enum class StepKind {
  kIncremental,   // Givens updates into R
  kBatchForced,   // BatchOptimize()
  kBatchOnMerge,  // two anchored groups joined: a gauge prior leaves R
  kBatchOnClock,  // batch_every_updates
  kBatchOnFill,   // nnz(R) grew batch_when_fill_grows times since the last reordering
};

struct PolicyInputs {
  bool forced = false;
  bool merge_pending = false;
  int updates_since_batch = 0;  // this update included
  int64_t nonzeros = 0;         // of R now
  int64_t nonzeros_after_batch = 0;
};

StepKind ChooseStep(const SmootherOptions& options, const PolicyInputs& in);

// Forced and merge steps iterate to convergence; periodic ones relinearise once (as
// iSAM's batch_optimization_step) unless converge_periodic_batches.
bool IteratesToConvergence(StepKind kind, const SmootherOptions& options);

enum class DriftAction {
  kNone,
  kPartialRelinearization,  // relinearise the drifted variables, re-eliminate their part
  kBatchStep,               // the old way: a full batch step
};

// After an incremental update: is drift looked at now (every relinearize_skip updates;
// `updates_since_check` includes this one)?
bool DriftCheckDue(const SmootherOptions& options, int updates_since_check);
// What a drift of `max_drift` (max-abs of any variable's delta) calls for.
DriftAction OnDrift(const SmootherOptions& options, double max_drift);

}  // namespace anchormap
