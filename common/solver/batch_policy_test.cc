#include "common/solver/batch_policy.h"

#include <gtest/gtest.h>

namespace anchormap {
namespace {

TEST(BatchPolicyTest, ChoosesTheStepByPriority) {
  SmootherOptions options;
  options.batch_every_updates = 10;
  options.batch_when_fill_grows = 4.0;
  PolicyInputs in;
  in.updates_since_batch = 3;
  in.nonzeros = 100;
  in.nonzeros_after_batch = 50;
  EXPECT_EQ(ChooseStep(options, in), StepKind::kIncremental);
  in.nonzeros = 201;
  EXPECT_EQ(ChooseStep(options, in), StepKind::kBatchOnFill);
  in.updates_since_batch = 10;
  EXPECT_EQ(ChooseStep(options, in), StepKind::kBatchOnClock);
  in.merge_pending = true;
  EXPECT_EQ(ChooseStep(options, in), StepKind::kBatchOnMerge);
  in.forced = true;
  EXPECT_EQ(ChooseStep(options, in), StepKind::kBatchForced);
  options.batch_every_updates = 0;
  options.batch_when_fill_grows = 0;
  EXPECT_EQ(ChooseStep(options, PolicyInputs{false, false, 1000, 1000000, 1}),
            StepKind::kIncremental);
}

TEST(BatchPolicyTest, ConvergenceAndDrift) {
  SmootherOptions options;
  EXPECT_TRUE(IteratesToConvergence(StepKind::kBatchOnMerge, options));
  EXPECT_FALSE(IteratesToConvergence(StepKind::kBatchOnClock, options));
  options.converge_periodic_batches = true;
  EXPECT_TRUE(IteratesToConvergence(StepKind::kBatchOnClock, options));

  EXPECT_FALSE(DriftCheckDue(options, 1));  // threshold 0: pure iSAM
  EXPECT_EQ(OnDrift(options, 5.0), DriftAction::kNone);
  options.relinearize_threshold = 0.01;
  options.relinearize_skip = 3;
  EXPECT_FALSE(DriftCheckDue(options, 2));
  EXPECT_TRUE(DriftCheckDue(options, 3));
  EXPECT_EQ(OnDrift(options, 0.01), DriftAction::kNone);
  EXPECT_EQ(OnDrift(options, 0.02), DriftAction::kPartialRelinearization);
  options.partial_relinearization = false;
  EXPECT_EQ(OnDrift(options, 0.02), DriftAction::kBatchStep);
}

TEST(BatchPolicyTest, CorrectionOutOfStepsWithinTheSkipBudgetHasConverged) {
  SmootherOptions options = ServerModeWithCorrectionOptions();  // 5 outer steps, 50 CG
  options.correction_skip_factor = 3.0;
  const double stop = 2.0;  // tolerance x chi2
  // At entry the skip budget (6) decides; once steps are taken, the tolerance (2).
  EXPECT_EQ(EndOfCorrection(options, 6.0, stop, 0, 0), CorrectionEnd::kConverged);
  EXPECT_EQ(EndOfCorrection(options, 6.5, stop, 0, 0), CorrectionEnd::kGoOn);
  EXPECT_EQ(EndOfCorrection(options, 2.0, stop, 3, 10), CorrectionEnd::kConverged);
  EXPECT_EQ(EndOfCorrection(options, 3.0, stop, 3, 10), CorrectionEnd::kGoOn);
  // Out of outer steps or CG iterations: within the budget converged, above it a stall.
  EXPECT_EQ(EndOfCorrection(options, 3.0, stop, 5, 10), CorrectionEnd::kConverged);
  EXPECT_EQ(EndOfCorrection(options, 6.0, stop, 5, 10), CorrectionEnd::kConverged);
  EXPECT_EQ(EndOfCorrection(options, 6.5, stop, 5, 10), CorrectionEnd::kStall);
  // Past the last outer step (a halving pass stepped over it): out of steps all the same.
  EXPECT_EQ(EndOfCorrection(options, 3.0, stop, 7, 10), CorrectionEnd::kConverged);
  EXPECT_EQ(EndOfCorrection(options, 6.5, stop, 7, 10), CorrectionEnd::kStall);
  EXPECT_EQ(EndOfCorrection(options, 3.0, stop, 2, 50), CorrectionEnd::kConverged);
  EXPECT_EQ(EndOfCorrection(options, 6.5, stop, 2, 50), CorrectionEnd::kStall);
  // Factor 1: the budget is the tolerance, so every correction out of steps above it
  // stalls.
  options.correction_skip_factor = 1.0;
  EXPECT_EQ(EndOfCorrection(options, 2.0, stop, 5, 10), CorrectionEnd::kConverged);
  EXPECT_EQ(EndOfCorrection(options, 2.5, stop, 5, 10), CorrectionEnd::kStall);
  EXPECT_EQ(EndOfCorrection(options, 2.5, stop, 0, 0), CorrectionEnd::kGoOn);
}

}  // namespace
}  // namespace anchormap
