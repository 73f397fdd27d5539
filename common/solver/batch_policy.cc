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

}  // namespace anchormap
