#include "server/match_options_fingerprint.h"

#include <gtest/gtest.h>

namespace anchormap {
namespace {

MappingServerOptions BothSources() {
  MappingServerOptions options;
  options.loop_closures = true;
  options.scan_encounters = true;
  return options;
}

// Options that change a match's result, or which matches are made, change the number;
// the worker count and the caches' memory budgets (bit-for-bit the same results) do not.
TEST(MatchOptionsFingerprintTest, ChangesWithTheOptionsThatChangeResults) {
  const uint64_t base = MatchOptionsFingerprint(BothSources());
  EXPECT_NE(base, 0u);
  EXPECT_EQ(base, MatchOptionsFingerprint(BothSources()));
  const auto changed = [&](auto edit) {
    MappingServerOptions o = BothSources();
    edit(&o);
    return MatchOptionsFingerprint(o) != base;
  };
  EXPECT_TRUE(changed([](MappingServerOptions* o) { o->loop.match.point_sigma_m = 0.04; }));
  EXPECT_TRUE(changed([](MappingServerOptions* o) { o->scan.match.min_score = 0.31; }));
  EXPECT_TRUE(changed(
      [](MappingServerOptions* o) { o->loop.match.covariance_model = MatchCovariance::kLaplace; }));
  EXPECT_TRUE(changed([](MappingServerOptions* o) { o->loop.reference.num_levels = 4; }));
  EXPECT_TRUE(changed([](MappingServerOptions* o) { o->loop.wide_max_window_m = 10.0; }));
  EXPECT_TRUE(changed([](MappingServerOptions* o) { o->loop.wide_weak_min_overlap = 0.7; }));
  EXPECT_TRUE(changed([](MappingServerOptions* o) { o->loop.refine_look_ahead_m = 1.0; }));
  EXPECT_TRUE(changed([](MappingServerOptions* o) { o->loop.refine_choice_radius_m = 0.0; }));
  EXPECT_TRUE(changed([](MappingServerOptions* o) { o->loop.wide_pair_min_separation_m = 2.0; }));
  EXPECT_TRUE(
      changed([](MappingServerOptions* o) { o->loop.wide_weak_partner_max_sigma_m = 0.2; }));
  EXPECT_TRUE(changed([](MappingServerOptions* o) { o->scan.submap_half_width = 4; }));
  EXPECT_TRUE(changed([](MappingServerOptions* o) { o->scan.global_budget.burst = 39.0; }));
  EXPECT_TRUE(changed([](MappingServerOptions* o) { o->scan.first_join_hold_s = 29.0; }));
  EXPECT_TRUE(changed([](MappingServerOptions* o) { o->scan.pcm_max_shared_look = 0.8; }));
  EXPECT_TRUE(changed([](MappingServerOptions* o) { o->scan.near_drift_per_m = 0.02; }));
  EXPECT_TRUE(changed([](MappingServerOptions* o) { o->scan.near_drift_rad_per_m = 0.002; }));
  EXPECT_TRUE(changed([](MappingServerOptions* o) { o->scan.near_catch_up_every = 0; }));
  EXPECT_TRUE(changed([](MappingServerOptions* o) { o->match_schedule.lag_s = 0.5; }));
  EXPECT_TRUE(changed([](MappingServerOptions* o) { o->smoother.convergence_step = 1e-6; }));
  EXPECT_TRUE(changed([](MappingServerOptions* o) { o->smoother.convergence_decrease = 1e-7; }));
  EXPECT_TRUE(changed([](MappingServerOptions* o) { o->smoother.givens_work_budget = 0.0; }));
  EXPECT_TRUE(changed([](MappingServerOptions* o) { o->loop_closures = false; }));
  EXPECT_FALSE(changed([](MappingServerOptions* o) { o->match_workers = 0; }));
  EXPECT_FALSE(changed([](MappingServerOptions* o) { o->loop.submap_cache.budget_mb = 1.0; }));
  EXPECT_FALSE(changed([](MappingServerOptions* o) { o->scan.submap_cache.budget_mb = 1.0; }));
}

// A source that is off has no say.
TEST(MatchOptionsFingerprintTest, AnOffSourcesOptionsDoNotCount) {
  MappingServerOptions a;
  MappingServerOptions b;
  b.loop.min_score = 0.9;
  b.scan.near_min_score = 0.9;
  EXPECT_EQ(MatchOptionsFingerprint(a), MatchOptionsFingerprint(b));
}

}  // namespace
}  // namespace anchormap
