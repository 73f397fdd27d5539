#include "server/scan_encounter_options.h"

namespace anchormap {

Status ScanEncounterOptions::Validate() const {
  if (submap_half_width < 0) return Status::Error("scan.submap_half_width must be >= 0");
  if (submap_stride < 1) return Status::Error("scan.submap_stride must be >= 1");
  if (!(max_range_m > 0)) return Status::Error("scan.max_range_m must be > 0");
  if (global_every < 1) return Status::Error("scan.global_every must be >= 1");
  if (max_global_per_keyframe < 0)
    return Status::Error("scan.max_global_per_keyframe must be >= 0");
  if (max_global_groups_per_keyframe < 0)
    return Status::Error("scan.max_global_groups_per_keyframe must be >= 0");
  if (Status s = global_budget.Validate(); !s.ok()) return s;
  // A keyframe's searches must fit in the bucket, or it would wait for ever.
  if (global_budget.burst < static_cast<double>(max_global_per_keyframe) *
                                static_cast<double>(max_global_groups_per_keyframe)) {
    return Status::Error(
        "scan.global_burst must be >= scan.max_global_per_keyframe x "
        "scan.max_global_groups_per_keyframe");
  }
  if (!(pcm_chi2 > 0) || !(gate_chi2 > 0)) return Status::Error("scan chi2 gates must be > 0");
  if (!(alternative_ratio >= 1)) return Status::Error("scan.alternative_ratio must be >= 1");
  if (!(first_join_hold_s >= 0)) return Status::Error("scan.first_join_hold_s must be >= 0");
  if (pcm_min_separation < 1) return Status::Error("scan.pcm_min_separation must be >= 1");
  if (!(pcm_min_separation_m >= 0)) return Status::Error("scan.pcm_min_separation_m must be >= 0");
  if (!(pcm_max_shared_view > 0 && pcm_max_shared_view <= 1))
    return Status::Error("scan.pcm_max_shared_view must be in (0, 1]");
  if (max_kept < 1) return Status::Error("scan.max_kept must be >= 1");
  if (!(first_join_max_sigma_m > 0) || !(first_join_max_sigma_rad > 0))
    return Status::Error("scan first-join sigmas must be > 0");
  if (!(join_check_radius_m >= 0) || !(join_check_range_m > 0) || !(verify_radius_m >= 0))
    return Status::Error(
        "scan.join_check_radius_m and verify_radius_m must be >= 0 and join_check_range_m > 0");
  if (!(join_max_conflict >= 0 && join_max_conflict <= 1))
    return Status::Error("scan.join_max_conflict must be in [0, 1]");
  if (!(verify_max_conflict >= 0 && verify_max_conflict <= 1) || verify_min_points < 0 ||
      !(verify_drift_per_m >= 0) || !(verify_drift_rad_per_m >= 0) ||
      !(verify_drift_rad_per_rad >= 0)) {
    return Status::Error(
        "scan map-verified candidates: verify_max_conflict in [0, 1], verify_min_points >= 0, "
        "verify_drift_per_m, verify_drift_rad_per_m and verify_drift_rad_per_rad >= 0");
  }
  if (guide_min_points < 0 || !(guide_max_distance_m >= 0))
    return Status::Error("scan guided search: guide_min_points and guide_max_distance_m >= 0");
  if (look_back_max_per_change < 0)
    return Status::Error("scan.look_back_max_per_change must be >= 0");
  if (!(free_space.resolution_m > 0) || !(free_space.wall_margin_m >= 0))
    return Status::Error("scan free-space grid: resolution_m > 0, wall_margin_m >= 0");
  if (!(near_distance_m >= 0)) return Status::Error("scan.near_distance_m must be >= 0");
  if (!(near_min_overlap >= 0 && near_min_overlap <= 1))
    return Status::Error("scan.near_min_overlap must be in [0, 1]");
  if (near_cooldown_keyframes < 0)
    return Status::Error("scan.near_cooldown_keyframes must be >= 0");
  if (!(near_index_refresh_s >= 0) || !(near_index_slack_m >= 0))
    return Status::Error("scan.near_index_refresh_s and near_index_slack_m must be >= 0");
  if (!(min_window_m > 0) || !(max_window_m >= min_window_m))
    return Status::Error("scan window: 0 < min_window_m <= max_window_m");
  if (!(min_window_rad > 0) || !(max_window_rad >= min_window_rad))
    return Status::Error("scan window: 0 < min_window_rad <= max_window_rad");
  if (!(near_wide_max_window_m >= 0) || near_pair_min_gap < 1 ||
      near_pair_max_gap < near_pair_min_gap || near_max_held < 1) {
    return Status::Error(
        "scan wide near search: near_wide_max_window_m >= 0, 1 <= near_pair_min_gap <= "
        "near_pair_max_gap, near_max_held >= 1");
  }
  if (near_catch_up_every < 0) return Status::Error("scan.near_catch_up_every must be >= 0");
  if (!(near_saturation_m >= 0)) return Status::Error("scan.near_saturation_m must be >= 0");
  if (near_max_partners < 0) return Status::Error("scan.near_max_partners must be >= 0");
  if (!(near_drift_per_m >= 0) || !(near_drift_rad_per_m >= 0))
    return Status::Error("scan near drift: near_drift_per_m and near_drift_rad_per_m >= 0");
  if (!(floor_sigma_m >= 0) || !(floor_sigma_rad >= 0))
    return Status::Error("scan covariance floors must be >= 0");
  if (max_waiting < 1) return Status::Error("scan.max_waiting must be >= 1");
  if (!(folded_wait_s >= 0)) return Status::Error("scan.folded_wait_s must be >= 0");
  if (Status s = reference.Validate(); !s.ok()) return s;
  if (Status s = submap_cache.Validate(); !s.ok()) return s;
  if (Status s = near_budget.Validate("scan.near_budget"); !s.ok()) return s;
  return match.Validate();
}

}  // namespace anchormap
