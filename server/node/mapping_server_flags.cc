#include "server/node/mapping_server_flags.h"

namespace anchormap {
namespace {

// OptionsLoader::Add with a help prefix, for every field type the loader takes.
struct PrefixedAdd {
  OptionsLoader* loader;
  std::string prefix;
  template <typename Field>
  void operator()(const std::string& key, const std::string& flag, Field* field,
                  const std::string& help) const {
    loader->Add(key, flag, field, prefix + help);
  }
};

}  // namespace

MappingServerFlags::MappingServerFlags(OptionsLoader* loader, MappingServerOptions* options,
                                       const std::string& help_prefix)
    : options_(options), formulation_(ToString(options->smoother.formulation)) {
  MappingServerOptions& s = *options;
  const PrefixedAdd add{loader, help_prefix};
  add("publish.map_period_s", "publish-period-s", &s.publish.map_period_s,
      "merged map after an update, at most this often, with the anchor covariances when due "
      "(--anchor-covariances-period-s) (s; 0 = every update)");
  add("publish.anchor_covariances_period_s", "anchor-covariances-period-s",
      &s.publish.anchor_covariances_period_s,
      "anchor covariances with a map at most this often, and at once when the anchored "
      "trajectories changed, with every full map (s; 0 = with every map)");
  add("publish.grid_period_s", "grid-period-s", &s.publish.grid_period_s,
      "occupancy grid tiles at most this often (s; 0 = only at the end of an offline run)");
  add("publish.map_full_period_s", "map-full-period-s", &s.publish.map_full_period_s,
      "every chunk of the merged map again about this often, the least recently sent a few at "
      "each map; the maps between carry the changed chunks (s; 0 = every chunk each time)");
  add("publish.chunks.chunk_poses", "map-chunk-poses", &s.publish.chunks.chunk_poses,
      "keyframes per chunk of the merged map");
  add("publish.chunks.max_moved_chunks", "map-max-moved-chunks", &s.publish.chunks.max_moved_chunks,
      "chunks of the merged map sent per map at most only because their poses moved, the "
      "farthest moved first; the rest at the next maps (0 = no limit)");
  add("publish.chunks.max_read_chunks", "map-max-read-chunks", &s.publish.chunks.max_read_chunks,
      "chunks of the merged map whose poses are read per map at most to see whether they "
      "moved, the least recently read first, besides those sent anyway (0 = every chunk)");
  add("publish.grid_full_period_s", "grid-full-period-s", &s.publish.grid_full_period_s,
      "every grid tile at most this often; the grids between carry the changed tiles (s; 0 = "
      "every tile each time)");
  add("publish.grid_max_moved", "grid-max-moved", &s.publish.grid_max_moved,
      "keyframes traced again per grid publication at most, the farthest moved first; the "
      "rest at the next ones (0 = no limit)");
  add("publish.grid_min_moved", "grid-min-moved", &s.publish.grid_min_moved,
      "keyframes traced again per grid publication at most, besides grid_moved_per_inserted "
      "per keyframe traced in (within grid_max_moved)");
  add("publish.grid_moved_per_inserted", "grid-moved-per-inserted",
      &s.publish.grid_moved_per_inserted,
      "keyframes traced again per grid publication at most for each keyframe traced in, besides "
      "grid_min_moved (within grid_max_moved)");
  add("delivery.resend_period_s", "resend-period-s", &s.delivery.resend_period_s,
      "ask a trajectory for missing keyframes / encounters at most this often (s)");
  add("smoother.solve_period_s", "solve-period-s", &s.solve_period_s,
      "one solver update folds in the inputs of this much data time (s; 0 = an update per "
      "input); sooner for new anchors and merges, and at the end");
  add("smoother.convergence_step", "convergence-step", &s.smoother.convergence_step,
      "batch steps iterate until the largest step component is below this");
  add("smoother.formulation", "formulation", &formulation_,
      "relative (anchors), global or global-moved (baselines)");
  add("smoother.batch_every_updates", "batch-every-updates", &s.smoother.batch_every_updates,
      "batch step (relinearise, reorder) every N updates; between them the estimate carries "
      "linearisation error");
  add("smoother.batch_when_fill_grows", "batch-when-fill-grows", &s.smoother.batch_when_fill_grows,
      "batch step when nnz(R) grew by this factor (0 = off)");
  add("smoother.relinearize_threshold", "relinearize-threshold", &s.smoother.relinearize_threshold,
      "relinearise (partial step) the variables whose estimate moved this far from their "
      "linearisation point (m / rad; 0 = off); with the correction on, only when it stalls");
  add("smoother.correction_tolerance", "correction-tolerance", &s.smoother.correction_tolerance,
      "after each update, conjugate-gradient steps move the estimate until the predicted "
      "decrease of chi2 is below this fraction of it (0 = off: relinearise on drift)");
  add("smoother.correction_skip_factor", "correction-skip", &s.smoother.correction_skip_factor,
      "an update is left uncorrected while the decrease a correction would bring stays below "
      "this multiple of correction_tolerance x chi2 (>= 1)");
  add("smoother.correction_local_hops", "correction-local-hops", &s.smoother.correction_local_hops,
      "correct an update first near its new factors (this many factor hops; 0 = off), the whole "
      "map only when what that leaves may exceed the skip budget");
  add("smoother.gauge_prior_sigma", "gauge-prior-sigma", &s.smoother.gauge_prior_sigma,
      "sigma of the gauge priors (m, rad)");
  add("table.max_held", "max-held-keyframes", &s.table.max_held,
      "keyframes held per trajectory waiting for a missing sequence number");
  add("table.max_hold_s", "max-hold-s", &s.table.max_hold_s,
      "a keyframe gap stays open this long (wall time online, data time offline) waiting for "
      "the resend before it is bridged, the last resort (s)");
  add("table.gap_covariance_scale", "gap-covariance-scale", &s.table.gap_covariance_scale,
      "bridged gap covariance = delta covariance x (missing + 1) x this");
  add("direct.max_wait_s", "encounter-max-wait-s", &s.direct.max_wait_s,
      "longest wait (data time) for an encounter's keyframes or an unknown robot (s)");
  add("direct.max_time_offset_s", "encounter-max-time-offset-s", &s.direct.max_time_offset_s,
      "an encounter's nearest keyframes must be this close in time (s)");
  add("direct.inflation_xy_base_m", "encounter-inflation-xy-base-m", &s.direct.inflation.xy_base_m,
      "sigma added to an encounter for clock offsets (m)");
  add("direct.inflation_xy_per_m", "encounter-inflation-xy-per-m", &s.direct.inflation.xy_per_m,
      "sigma added per metre of time correction");
  add("direct.inflation_theta_base_rad", "encounter-inflation-theta-base-rad",
      &s.direct.inflation.theta_base_rad, "heading sigma added for clock offsets (rad)");
  add("loop.enabled", "loop-closures", &s.loop_closures,
      "find loop closures within a trajectory by scan matching");
  add("loop.max_distance_m", "loop-max-distance-m", &s.loop.max_distance_m,
      "a loop-closure candidate may lie this close to the keyframe (m)");
  add("loop.saturation_m", "loop-saturation-m", &s.loop.saturation_m,
      "a loop-closure candidate is not matched when an entered closure has both ends within "
      "this much path of the keyframe's and the candidate's (m; 0 = always matched)");
  add("loop.min_overlap", "loop-min-overlap", &s.loop.min_overlap,
      "a loop closure's match needs this fraction of points near the submap's walls");
  add("loop.submap_cache_mb", "loop-submap-cache-mb", &s.loop.submap_cache.budget_mb,
      "loop closures: memory kept for built candidate submaps, least recently used dropped "
      "beyond (MB, estimated)");
  add("loop.budget_per_s", "loop-budget-per-s", &s.loop.budget.units_per_s,
      "loop closures: matching work per second of data, whole team (units: a local match 1, "
      "a wide search 8, or its branch and bound's scored nodes / 25000 when more); short of it "
      "the keyframes whose trajectory drove farthest since its last served one go first (0 = "
      "no bound)");
  add("loop.budget_burst", "loop-budget-burst", &s.loop.budget.burst,
      "loop closures: most matching work saved up (units)");
  add("scan.enabled", "scan-encounters", &s.scan_encounters,
      "find encounters between trajectories by scan matching");
  add("match.workers", "match-workers", &s.match_workers,
      "worker threads of the scan-matching sources (0: the server's thread)");
  add("match.lag_s", "match-lag-s", &s.match_schedule.lag_s,
      "a match is used once the inputs reach its keyframe's time plus this (data time, s)");
  add("order.patience_s", "order-patience-s", &s.order.patience_s,
      "a trajectory silent this long stops holding the others' inputs (s)");
  add("order.settle_s", "order-settle-s", &s.order.settle_s,
      "online, an input waits this long after its arrival before it is ordered (s)");
  add("order.settle_offline", "order-settle-offline", &s.order.settle_offline,
      "with --log: settle in data time too (the log is a recording of a bus, as the "
      "online server heard it; false: the log's inputs are complete, released at once)");
  add("scan.near_distance_m", "scan-near-distance-m", &s.scan.near_distance_m,
      "joined trajectories: window search when predicted this close (m)");
  add("scan.near_min_overlap", "scan-near-min-overlap", &s.scan.near_min_overlap,
      "joined trajectories: a match needs this overlap");
  add("scan.near_wide_max_window_m", "scan-near-wide-max-window-m", &s.scan.near_wide_max_window_m,
      "joined trajectories whose estimate drifted apart: the window grows to 3 sigma up to "
      "this (m; 0 = off); such a match enters only with a second one of the pair that agrees");
  add("scan.near_saturation_m", "scan-near-saturation-m", &s.scan.near_saturation_m,
      "joined trajectories already tied within this drive of here (both paths, through the "
      "ties) are not near-searched here (m; 0 = always searched)");
  add("scan.near_max_partners", "scan-near-max-partners", &s.scan.near_max_partners,
      "joined trajectories near-searched per keyframe at most, nearest first (0 = all)");
  add("scan.near_budget_per_s", "scan-near-budget-per-s", &s.scan.near_budget.units_per_s,
      "joined trajectories: near searches per second of data, whole team; short of it the "
      "keyframes whose trajectory drove farthest since its last served one go first (0 = no "
      "bound)");
  add("scan.near_budget_burst", "scan-near-budget-burst", &s.scan.near_budget.burst,
      "joined trajectories: most near searches saved up");
  add("scan.global_every", "scan-global-every", &s.scan.global_every,
      "unjoined trajectories: every N-th keyframe is searched globally");
  add("scan.max_global_per_keyframe", "scan-max-global-per-keyframe",
      &s.scan.max_global_per_keyframe,
      "unjoined trajectories: submaps of each target searched per keyframe (taken in turn)");
  add("scan.max_global_groups_per_keyframe", "scan-max-global-groups-per-keyframe",
      &s.scan.max_global_groups_per_keyframe,
      "unjoined trajectories: other groups searched per keyframe (those searched least)");
  add("scan.global_searches_per_s", "scan-global-searches-per-s",
      &s.scan.global_budget.searches_per_s,
      "unjoined trajectories: global searches (submaps) per second of data, whole team");
  add("scan.global_burst", "scan-global-burst", &s.scan.global_budget.burst,
      "unjoined trajectories: most global searches saved up");
  add("scan.submap_cache_mb", "scan-submap-cache-mb", &s.scan.submap_cache.budget_mb,
      "scan encounters: memory kept for built submaps, least recently used dropped beyond "
      "(MB, estimated)");
  add("reduced_graph.enabled", "reduced-graph", &s.reduced_graph.enabled,
      "reduced pose graph: a keyframe in an already mapped place folds onto an existing node "
      "(verified by a scan match) instead of becoming a new variable, so the graph grows with "
      "the area, not with time (its folds are in the snapshots; updates never deferred)");
  add("reduced_graph.radius_m", "reduced-graph-radius-m", &s.reduced_graph.radius_m,
      "reduced graph: a node is a fold candidate when the keyframe's predicted position is this "
      "close (m, (0, 10])");
  add("reduced_graph.angle_deg", "reduced-graph-angle-deg", &s.reduced_graph.angle_deg,
      "reduced graph: ... and its predicted heading this close (degrees, (0, 180])");
  add("reduced_graph.laplace_covariance", "reduced-graph-laplace-covariance",
      &s.reduced_graph.laplace_covariance,
      "reduced graph: the fold's match covariance by the Laplace approximation (false: the "
      "score distribution's samples, as the loop closures')");
  add("reduced_graph.refine_chained_from_guess", "reduced-graph-refine-chained",
      &s.reduced_graph.refine_chained_from_guess,
      "reduced graph: a fold predicted from its predecessor's own match is refined from the "
      "prediction without the lattice search (false: searched as the others)");
  add("reduced_graph.reference_cache", "reduced-graph-reference-cache",
      &s.reduced_graph.reference_cache,
      "reduced graph: node references kept built, least recently used dropped beyond (a few MB "
      "each)");
  add("grid.resolution_m", "grid-resolution-m", &s.publish.grid.resolution_m, "cell size (m)");
  add("grid.tile_size_cells", "grid-tile-size", &s.publish.grid.tile_size_cells,
      "cells per tile side");
  add("grid.max_ray_length_m", "grid-max-ray-m", &s.publish.grid.max_ray_length_m,
      "beams are traced at most this far (m)");
  add("grid.no_return_as_free", "grid-no-return-as-free", &s.publish.grid.no_return_as_free,
      "trace no-return beams as free space up to the ray limit");
}

Status MappingServerFlags::Apply() const {
  const std::optional<Formulation> formulation = ParseFormulation(formulation_);
  if (!formulation) {
    return Status::Error("--formulation: '" + formulation_ +
                         "' is not relative, global or global-moved");
  }
  options_->smoother.formulation = *formulation;
  return Status::Ok();
}

}  // namespace anchormap
