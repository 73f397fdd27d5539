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

enum class CorrectionEnd {
  kGoOn,  // take another correction step
  kConverged,
  kStall,  // out of steps above the budget: R too stale (relinearize_when_correction_stalls)
};

// The conjugate-gradient correction after a gradient pass (correction_cg_iterations):
// `decrease` is the chi2 decrease R^T R predicts from here, `stop` the tolerance
// (correction_tolerance x chi2), `outer` the outer steps taken and `cg_iterations` the
// conjugate-gradient iterations so far. At entry the update may be left within the skip
// budget (correction_skip_factor x stop); once steps are taken they go on to the
// tolerance, and a correction out of steps within that budget is converged, not a stall:
// it leaves no more than a skipped update may (the next update's skip test starts from
// its decrease), and a stall's partial step would buy less than that.
CorrectionEnd EndOfCorrection(const SmootherOptions& options, double decrease, double stop,
                              int outer, int cg_iterations);

}  // namespace anchormap
