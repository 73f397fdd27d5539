#include "common/solver/batch_policy.h"

namespace anchormap {

StepKind ChooseStep(const SmootherOptions& options, const PolicyInputs& in) {
  if (in.forced) return StepKind::kBatchForced;
  if (in.merge_pending) return StepKind::kBatchOnMerge;
  if (options.batch_every_updates > 0 && in.updates_since_batch >= options.batch_every_updates) {
    return StepKind::kBatchOnClock;
  }
  if (options.batch_when_fill_grows > 0 && in.nonzeros_after_batch > 0 &&
      in.nonzeros > options.batch_when_fill_grows * in.nonzeros_after_batch) {
    return StepKind::kBatchOnFill;
  }
  return StepKind::kIncremental;
}

bool IteratesToConvergence(StepKind kind, const SmootherOptions& options) {
  return kind == StepKind::kBatchForced || kind == StepKind::kBatchOnMerge ||
         options.converge_periodic_batches;
}

bool DriftCheckDue(const SmootherOptions& options, int updates_since_check) {
  return options.relinearize_threshold > 0 && updates_since_check >= options.relinearize_skip;
}

DriftAction OnDrift(const SmootherOptions& options, double max_drift) {
  if (!(options.relinearize_threshold > 0) || !(max_drift > options.relinearize_threshold)) {
    return DriftAction::kNone;
  }
  return options.partial_relinearization ? DriftAction::kPartialRelinearization
                                         : DriftAction::kBatchStep;
}

CorrectionEnd EndOfCorrection(const SmootherOptions& options, double decrease, double stop,
                              int outer, int cg_iterations) {
  const double budget = options.correction_skip_factor * stop;
  if (decrease <= (outer == 0 ? budget : stop)) return CorrectionEnd::kConverged;
  // At or past the last outer step: a pass that halves an overshooting step counts as one,
  // so the count can step over the limit (a halving at the limit let 5-22 corrections per
  // 100 x 180 run go on to the CG limit).
  if (outer >= options.correction_iterations || cg_iterations >= options.correction_cg_iterations) {
    // At 100 robots x 180 s (seed 2) a third of the stalls ended 5 outer steps at 1.0-1.8
    // x the tolerance, and each paid a partial step over 4-5 k drifted variables after
    // which the correction converged at entry.
    return decrease <= budget ? CorrectionEnd::kConverged : CorrectionEnd::kStall;
  }
  return CorrectionEnd::kGoOn;
}

}  // namespace anchormap
