#include "server/match_options_fingerprint.h"

namespace anchormap {
namespace {

// A field added to one of these structs changes its size: these fail to compile until the
// field is hashed below (or said not to change results) and the sizes updated. (x86-64,
// gcc and clang; elsewhere the check is off rather than wrong.)
#if defined(__x86_64__)
// MatchOptions' covariance_min_score / covariance_min_overlap are not hashed: a result below
// them is one its caller discards unused, so the results used are the same.
static_assert(sizeof(MatchOptions) == 48, "new MatchOptions field: add it to the fingerprint");
static_assert(sizeof(ScanReferenceOptions) == 32,
              "new ScanReferenceOptions field: add it to the fingerprint");
static_assert(sizeof(LoopClosureOptions) == 448,
              "new LoopClosureOptions field: add it to the fingerprint");
static_assert(sizeof(ScanEncounterOptions) == 560,
              "new ScanEncounterOptions field: add it to the fingerprint");
static_assert(sizeof(SmootherOptions) == 136,
              "new SmootherOptions field: add it to the fingerprint");
#endif

class Fnv1a {
 public:
  void Bytes(const void* data, size_t size) {
    const auto* p = static_cast<const uint8_t*>(data);
    for (size_t i = 0; i < size; ++i) {
      hash_ ^= p[i];
      hash_ *= 0x100000001b3ULL;
    }
  }
  void F(double v) { Bytes(&v, sizeof v); }
  void I(int64_t v) { Bytes(&v, sizeof v); }
  void B(bool v) { I(v ? 1 : 0); }
  uint64_t value() const { return hash_ == 0 ? 1 : hash_; }

 private:
  uint64_t hash_ = 0xcbf29ce484222325ULL;
};

void Add(Fnv1a* h, const MatchBudgetOptions& b) {
  h->F(b.units_per_s);
  h->F(b.burst);
  h->F(b.skip_priority_m);
}

void Add(Fnv1a* h, const MatchOptions& m) {
  h->F(m.min_score);
  h->F(m.point_sigma_m);
  h->F(m.overlap_distance_m);
  h->B(m.refine);
  h->B(m.covariance);
  // Hashed only when not the default, so that the default's fingerprint (in snapshots) stays.
  if (m.covariance_model != MatchCovariance::kScoreDistribution) {
    h->I(static_cast<int64_t>(m.covariance_model));
  }
}

void Add(Fnv1a* h, const ScanReferenceOptions& r) {
  h->F(r.resolution_m);
  h->F(r.likelihood_sigma_m);
  h->F(r.max_join_gap_m);
  h->I(r.num_levels);
}

void Add(Fnv1a* h, const LoopClosureOptions& o) {
  h->I(o.min_index_gap);
  h->F(o.max_distance_m);
  h->F(o.candidate_chi2);
  h->F(o.gate_chi2);
  h->I(o.max_candidates);
  h->I(o.cooldown_keyframes);
  h->F(o.saturation_m);
  h->I(o.submap_half_width);
  h->F(o.max_range_m);
  h->F(o.min_score);
  h->F(o.min_overlap);
  h->F(o.min_window_m);
  h->F(o.max_window_m);
  h->F(o.min_window_rad);
  h->F(o.max_window_rad);
  h->F(o.floor_sigma_m);
  h->F(o.floor_sigma_rad);
  h->I(o.max_waiting);
  h->B(o.wide_search);
  h->F(o.drift_per_m);
  h->F(o.drift_rad_per_m);
  h->I(o.wide_quiet_keyframes);
  h->F(o.wide_sigmas);
  h->F(o.wide_max_window_m);
  h->F(o.wide_max_window_rad);
  h->I(o.wide_submap_half_width);
  h->B(o.wide_submap_by_place);
  h->B(o.wide_submap_place_keeps_index);
  h->I(o.wide_submap_max_keyframes);
  h->F(o.wide_submap_spacing_m);
  h->F(o.wide_submap_spacing_rad);
  h->I(o.wide_refine_half_width);
  h->I(o.wide_every_keyframes);
  h->F(o.wide_min_score);
  h->F(o.wide_min_overlap);
  h->F(o.wide_pair_chi2);
  h->I(o.wide_pair_min_gap);
  h->I(o.wide_pair_max_gap);
  h->I(o.wide_max_kept);
  h->F(o.wide_weak_min_overlap);
  h->F(o.wide_pair_min_separation_m);
  h->F(o.refine_look_ahead_m);
  h->F(o.refine_choice_radius_m);
  h->F(o.wide_weak_partner_max_sigma_m);
  Add(h, o.budget);
  h->F(o.budget_wide_units);
  h->F(o.budget_wide_nodes_per_unit);
  Add(h, o.reference);
  Add(h, o.match);
}

void Add(Fnv1a* h, const ScanEncounterOptions& o) {
  h->I(o.submap_half_width);
  h->I(o.submap_stride);
  h->F(o.max_range_m);
  h->I(o.global_every);
  h->I(o.max_global_per_keyframe);
  h->I(o.max_global_groups_per_keyframe);
  h->F(o.global_budget.searches_per_s);
  h->F(o.global_budget.burst);
  Add(h, o.near_budget);
  h->F(o.global_min_score);
  h->F(o.global_min_overlap);
  h->F(o.pcm_chi2);
  h->I(o.pcm_min_separation);
  h->F(o.pcm_min_separation_m);
  h->F(o.pcm_max_shared_view);
  h->F(o.pcm_max_shared_look);
  h->I(o.max_kept);
  h->F(o.alternative_ratio);
  h->F(o.first_join_max_sigma_m);
  h->F(o.first_join_max_sigma_rad);
  h->F(o.first_join_hold_s);
  h->F(o.join_check_radius_m);
  h->F(o.join_check_range_m);
  h->F(o.join_max_conflict);
  h->F(o.verify_radius_m);
  h->F(o.verify_max_conflict);
  h->I(o.verify_min_points);
  h->F(o.verify_drift_per_m);
  h->F(o.verify_drift_rad_per_m);
  h->F(o.verify_drift_rad_per_rad);
  h->I(o.guide_min_points);
  h->F(o.guide_max_distance_m);
  h->I(o.look_back_max_per_change);
  h->F(o.free_space.resolution_m);
  h->F(o.free_space.wall_margin_m);
  h->F(o.near_distance_m);
  h->F(o.near_min_overlap);
  h->F(o.near_min_score);
  h->I(o.near_cooldown_keyframes);
  h->F(o.near_index_refresh_s);
  h->F(o.near_index_slack_m);
  h->F(o.gate_chi2);
  h->F(o.min_window_m);
  h->F(o.max_window_m);
  h->F(o.min_window_rad);
  h->F(o.max_window_rad);
  h->F(o.near_wide_max_window_m);
  h->F(o.near_drift_per_m);
  h->F(o.near_drift_rad_per_m);
  h->I(o.near_catch_up_every);
  h->F(o.near_saturation_m);
  h->I(o.near_max_partners);
  h->I(o.near_pair_min_gap);
  h->I(o.near_pair_max_gap);
  h->I(o.near_max_held);
  h->F(o.floor_sigma_m);
  h->F(o.floor_sigma_rad);
  h->I(o.max_waiting);
  // Hashed only when set, so that fingerprints recorded before it existed still hold (the
  // server sets it from its solve period with the reduced graph only).
  if (o.folded_wait_s != 0) h->F(o.folded_wait_s);
  Add(h, o.reference);
  Add(h, o.match);
}

void Add(Fnv1a* h, const SmootherOptions& s) {
  h->I(static_cast<int64_t>(s.formulation));
  h->I(static_cast<int64_t>(s.method));
  h->I(s.batch_every_updates);
  h->F(s.batch_when_fill_grows);
  h->F(s.givens_work_budget);
  h->F(s.backsubstitution_threshold);
  h->F(s.relinearize_threshold);
  h->B(s.partial_relinearization);
  h->I(s.relinearize_skip);
  h->F(s.correction_tolerance);
  h->I(s.correction_iterations);
  h->B(s.relinearize_when_correction_stalls);
  // Hashed only when set, so that fingerprints recorded before the option existed still hold.
  if (s.correction_cg_iterations != 0) h->I(s.correction_cg_iterations);
  h->F(s.correction_skip_factor);
  h->B(s.partial_merges);
  h->B(s.converge_periodic_batches);
  h->F(s.convergence_step);
  h->I(s.max_batch_iterations);
  if (s.convergence_decrease != 0) h->F(s.convergence_decrease);    // only when set, as above
  if (s.correction_local_hops != 0) h->I(s.correction_local_hops);  // the same
  if (!s.latest_poses_last) h->B(s.latest_poses_last);  // the same: when not the library's
  h->F(s.dogleg_initial_radius);
  h->F(s.gauge_prior_sigma);
}

}  // namespace

uint64_t MatchOptionsFingerprint(const MappingServerOptions& options) {
  Fnv1a h;
  const char kLayout[] = "anchormap match options 2";  // bumped when the field list changes
  h.Bytes(kLayout, sizeof kLayout);
  h.B(options.loop_closures);
  if (options.loop_closures) Add(&h, options.loop);
  h.B(options.scan_encounters);
  if (options.scan_encounters) Add(&h, options.scan);
  h.F(options.match_schedule.lag_s);
  Add(&h, options.smoother);
  return h.value();
}

}  // namespace anchormap
