#pragma once
// Options of the incremental smoother (one source of defaults; see Validate()).

#include <optional>
#include <string>
#include "common/util/status.h"

namespace anchormap {

// How trajectories are tied into one map (docs/METHOD.md sections 3 and 4).
enum class Formulation {
  // Each trajectory in its own local frame plus an anchor T_global_local, created at its
  // first encounter (the thesis' method).
  kRelative,
  // All poses in one global frame; each trajectory starts with a prior at the origin
  // that is removed when its first encounter joins it to another group (the baseline).
  kGlobal,
  // As kGlobal, but the joining group is first moved rigidly to agree with the encounter
  // (an O(poses) re-initialisation that anchors make unnecessary).
  kGlobalMoved,
};

enum class NonlinearMethod {
  kGaussNewton,
  kDogLeg,  // Powell's dog-leg with a trust region, in batch steps
};

struct SmootherOptions {
  Formulation formulation = Formulation::kRelative;
  NonlinearMethod method = NonlinearMethod::kGaussNewton;

  // A batch step (relinearise every factor, reorder with CCOLAMD, refactor with CHOLMOD,
  // iterate to convergence) every this many updates. 0 = never on a clock (batch steps
  // still happen at group merges and on evidence, see below). 1 = pure batch.
  int batch_every_updates = 100;

  // Batch on evidence: when the number of non-zeros of R has grown by this factor since
  // the last reordering (fill-in from incremental updates). 0 disables.
  double batch_when_fill_grows = 4.0;
  // With batch_when_fill_grows, an update whose Givens rotations would take more than this
  // many units of work (a triple of rows carried through one block of R,
  // SparseR::eliminated_work) per non-zero of R after its last ordering is a batch step on
  // fill instead; the work is predicted from the patterns, before any arithmetic. About
  // what that batch step costs (100 x 180: 12.6 ns of CPU per unit, a fill batch step
  // 400-450 ns per non-zero). The fill budget misses an update whose many rows meet R's
  // wide rows near the root while adding little fill: after a merge, the caught-up
  // encounters (100 x 180 seed 1: 752 triples through 1419 rows, 44 units per non-zero,
  // 1.3 s of CPU). 0 disables.
  double givens_work_budget = 32.0;

  // Back-substitution after each incremental update recomputes only rows whose inputs
  // changed; a change of a variable below this (max-abs of its 3-vector) does not
  // propagate further (iSAM2's wildfire threshold). 0 = exact full back-substitution.
  double backsubstitution_threshold = 0.0;

  // Batch on drift: right after an incremental update, a batch step when some variable's
  // estimate has moved more than this from the point its factors were linearised at
  // (max-abs of the (x, y, theta) step; metres / radians). iSAM's Givens updates keep old
  // Jacobians; when an anchor turns by degrees, encounters linearised at different anchor
  // headings disagree by metres (lever arm x angle) and R gains information no
  // measurement gave: overconfident, biased anchors until the next batch step. iSAM2
  // relinearises on the same kind of threshold. 0 disables (pure iSAM).
  double relinearize_threshold = 0.0;

  // How drift is handled: true relinearises only the drifted variables and re-eliminates
  // the part of R that depends on them (iSAM2's partial relinearisation on R, counted in
  // stats().partial_relinearizations); false runs a full batch step (batch_steps_on_drift).
  bool partial_relinearization = true;
  // Drift is looked at every this many updates (iSAM2's relinearizeSkip); 1 = every update.
  int relinearize_skip = 1;

  // Nonlinear correction of the estimate after every incremental update (0 = off): the
  // estimate is moved toward the optimum of the nonlinear problem by steps
  // h = -(R^T R)^-1 g, g the gradient of chi2 at the estimate (every factor in R at its
  // current values), R (linearised at older points) as the preconditioner, until the
  // predicted chi2 decrease g^T (R^T R)^-1 g is below this fraction of chi2, at most
  // correction_iterations steps. The correction is kept apart from R and d.
  double correction_tolerance = 0.0;
  int correction_iterations = 5;
  // With correction_tolerance: look at drift (relinearize_threshold) only after an update
  // whose correction did not converge within correction_iterations (R too stale to
  // serve as the preconditioner), instead of after every update.
  bool relinearize_when_correction_stalls = false;
  // With correction_tolerance: each correction step solves the Gauss-Newton system at the
  // estimate, J^T J h = -g, by conjugate gradients preconditioned with R^T R (a Krylov
  // method copes with a stale preconditioner where the fixed-point steps stall), to an
  // inner tolerance of correction_tolerance x chi2. More than correction_cg_iterations
  // conjugate-gradient iterations in one update count as a stall (the preconditioner is
  // too stale: relinearize_when_correction_stalls relinearises then). 0 = fixed-point steps.
  int correction_cg_iterations = 0;
  // With correction_cg_iterations: an update is left uncorrected while the decrease of chi2
  // a correction would bring stays below this multiple of correction_tolerance x chi2
  // (judged first by a bound from the last correction's predicted decrease and the new
  // factors' errors since, then by the correction's first solve); a correction that runs
  // still goes on to correction_tolerance. Why: most corrected updates of a large map take
  // one CG step that costs solves with all of R, while the check asks each step for
  // 1e-3 x chi2. An uncorrected update's excess over its optimum stays near the budget
  // (city10000's worst of 100 sampled steps: 2.8e-4 at factor 3, 4.0e-4 at 4, 5.0e-4 at 5,
  // 5.9e-4 at 6; 3914 -> 3302 of 10000 updates corrected from 3 to 5), so 5 keeps half of
  // the 1e-3 as margin for the model's error (city10000 ~12 % faster than at 3). 100
  // simulated robots x 180 s, seeds 1 / 2 / 3, merged ATE at 3: 0.317 / 0.329 / 0.400 m,
  // at 5: 0.288 / 0.399 / 0.344 m (one seed's ATE moves by round-off; no worse across
  // seeds). 1 = skip only within correction_tolerance.
  double correction_skip_factor = 5.0;
  // With correction_cg_iterations: an update that the skip test would correct is first
  // corrected near its new factors only: Gauss-Newton on the variables within this many
  // factor hops of theirs (at most kLocalCorrectionMaxVariables, anchors excluded), every
  // other variable fixed. The correction over the whole map runs only when a bound on the
  // decrease it would still bring (the skip test's, with the moved factors' change of
  // gradient) exceeds the skip budget. Why: at 20 robots nearly every update is corrected
  // and each correction streams the whole map several times. 0 = off. The local moves'
  // reference values are in the snapshot state (SmootherState, format 11).
  int correction_local_hops = 0;
  static constexpr size_t kLocalCorrectionMaxVariables = 400;
  // A local attempt only when the factors new since the last correction see at most this
  // many variables: a large team's update spans many trajectories (100 robots: median 150
  // such variables, 9 of 252 corrected updates at most 50), and its correction moves whole
  // trajectories, so the local bound mostly fails there and the update pays both; at 20
  // robots 96 % of the corrected updates have at most 50 (docs/ARCHITECTURE.md, corr23).
  static constexpr size_t kLocalCorrectionMaxSeedVariables = 50;

  // Relative formulation: two anchored groups that join are merged by a partial step
  // instead of a batch step. The absorbed group's gauge prior leaves R and its anchors
  // are relinearised where the encounter puts them; only the rows of R that depend on
  // those anchors are re-eliminated (anchors sit at the end of the ordering, so that is
  // the tail of R and the encounter poses' paths to it). Counted in stats().partial_merges.
  // With relinearize_threshold, drift left by the merge is relinearised right away (up to
  // three partial steps). Off: a batch step iterated to convergence (iSAM's way; the
  // thesis' iteration counts assume it). Other formulations always merge by batch steps.
  bool partial_merges = false;
  // Orderings (batch steps, and partial steps' local ones) put each trajectory's newest
  // pose last, with the anchors, so that the next odometry rows enter R at its end. The
  // price is a dense clique of all of them at R's root in every ordering: with a hundred
  // trajectories it held a third of a fill batch step's factorisation (docs/ARCHITECTURE.md,
  // fill22). false: only the anchors and the newest poses of trajectories without an anchor
  // (a lone trajectory adds no clique) are kept last; an anchored trajectory's first new
  // odometry row after an ordering then walks its predecessor's path up R once.
  bool latest_poses_last = true;

  // Periodic batch steps (on the clock or on fill) relinearise once, as iSAM does; with
  // this set they iterate to convergence like merge steps and BatchOptimize() (the
  // thesis' protocol for counting iterations).
  bool converge_periodic_batches = false;

  // Batch-step convergence: stop iterating when the largest component of the step is
  // below this (metres / radians) or after max_batch_iterations.
  double convergence_step = 1e-4;
  int max_batch_iterations = 50;
  // Batch-step convergence also stops when the chi2 decrease the step predicts (|d|^2 of
  // the fresh R) is below this fraction of chi2 and the step did not raise chi2 (0 = off).
  // For weakly constrained directions that keep the largest step component above
  // convergence_step after chi2 stopped changing. Off by default: the final batch steps of
  // M3500 and city10000 (server mode) stop at the same iteration with 1e-6 (ARCHITECTURE).
  double convergence_decrease = 0.0;

  // Dog-leg trust region, initial radius (in whitened step units).
  double dogleg_initial_radius = 1.0;

  // Standard deviation of the gauge priors (trajectory origins, first anchor of a group):
  // metres for x and y, radians for theta. Small: they fix the gauge, not a measurement.
  double gauge_prior_sigma = 1e-3;

  // Returns a readable error for an inconsistent setting.
  Status Validate() const {
    if (batch_every_updates < 0) return Status::Error("batch_every_updates must be >= 0");
    if (batch_when_fill_grows != 0 && batch_when_fill_grows <= 1.0) {
      return Status::Error("batch_when_fill_grows must be 0 (off) or > 1");
    }
    if (!(givens_work_budget >= 0)) return Status::Error("givens_work_budget must be >= 0");
    if (!(relinearize_threshold >= 0)) return Status::Error("relinearize_threshold must be >= 0");
    if (relinearize_skip < 1) return Status::Error("relinearize_skip must be >= 1");
    if (backsubstitution_threshold < 0)
      return Status::Error("backsubstitution_threshold must be >= 0");
    if (!(correction_tolerance >= 0)) return Status::Error("correction_tolerance must be >= 0");
    if (correction_iterations < 1) return Status::Error("correction_iterations must be >= 1");
    if (correction_cg_iterations < 0) return Status::Error("correction_cg_iterations must be >= 0");
    if (!(correction_skip_factor >= 1.0))
      return Status::Error("correction_skip_factor must be >= 1");
    if (correction_local_hops < 0) return Status::Error("correction_local_hops must be >= 0");
    if (!(convergence_step > 0)) return Status::Error("convergence_step must be > 0");
    if (max_batch_iterations < 1) return Status::Error("max_batch_iterations must be >= 1");
    if (!(convergence_decrease >= 0)) return Status::Error("convergence_decrease must be >= 0");
    if (!(dogleg_initial_radius > 0)) return Status::Error("dogleg_initial_radius must be > 0");
    if (!(gauge_prior_sigma > 0)) return Status::Error("gauge_prior_sigma must be > 0");
    return Status::Ok();
  }
};

// The mapping server's configuration: relinearise at 0.01 by partial steps, merge by
// partial steps, no batch step on a clock; batch steps only when R's fill has grown
// batch_when_fill_grows (1.5) times since the last ordering (amortised: with a map that
// grows, their number grows with the logarithm of its size), and the final one at the end of
// input. Why relinearisation: the server publishes estimates and covariances after every
// update, and pure iSAM let the demo's estimates wander 1.97 m from their linearisation
// point (chi2 135 against an optimum of 78, an anchor sigma of 2.8 m against 3.9 m at
// convergence). Why no clock: a batch step costs the whole map, and one every 10 updates
// made the cost per update grow with the map (issue 12).
SmootherOptions ServerModeOptions();
// The mapping server's solver: ServerModeOptions() with the estimate corrected after each
// update by conjugate gradients (R^T R preconditions; tolerance 1e-4 x chi2, at most 5 outer
// steps and 50 CG iterations, partial steps only when the correction stalls).
// anchormap-bench-solver's equivalent: --server-mode --correct 1e-4 --correct-iterations 5
// --relinearize-on-stall --correct-cg 50.
SmootherOptions ServerModeWithCorrectionOptions();

const char* ToString(Formulation formulation);
std::optional<Formulation> ParseFormulation(const std::string& text);

}  // namespace anchormap
