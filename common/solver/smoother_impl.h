#pragma once
// Internal to common/solver: the smoother's state (Smoother::Impl), shared by its parts:
//   smoother.cc            graph bookkeeping, anchors and merges, queries, the public API
//   smoother_aliases.cc    the public API over pose aliases (folded keyframes): measurements
//                          moved onto nodes, queries resolved through them
//   smoother_update.cc     Update() and its steps: incremental (Givens), partial
//                          relinearisation, batch; the policy is batch_policy.h
//   smoother_nonlinear.cc  the iterations of a batch step: Gauss-Newton, dog-leg
//   smoother_correction.cc the correction of the estimate after an update

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "common/solver/anchor_groups.h"
#include "common/solver/batch_factorization.h"
#include "common/solver/batch_policy.h"
#include "common/solver/covariances.h"
#include "common/solver/factor.h"
#include "common/solver/factor_record.h"
#include "common/solver/flat_r.h"
#include "common/solver/incremental_gradient.h"
#include "common/solver/path_solve.h"
#include "common/solver/smoother.h"
#include "common/solver/smoother_state.h"
#include "common/solver/sparse_r.h"

namespace anchormap {
namespace smoother_internal {

// The system is linearised at `linearization` (theta); R delta = d gives the current
// solution delta relative to it (additive in x, y, theta, as iSAM's Pose2d).
struct Variable {
  Key key;
  Pose2 linearization;
  int position = -1;  // elimination position; -1 while pending (not yet in R)
};

// Where a factor's rows in R were linearised: J(x - theta) = J (at - theta) - e(at).
// Rows added by Givens rotations are linearised at the estimate of their update, rows
// of a batch step at the linearisation point.
struct FactorLinearization {
  std::array<Pose2, kMaxFactorKeys> at;
  bool in_r = false;
};

struct TrajectoryInfo {
  int32_t max_index = 0;
  int num_poses = 0;
  int64_t origin_prior = -1;  // factor id of the prior on the first pose
  bool anchored = false;      // relative formulation: has an anchor variable
};

inline Pose2 Retract(const Pose2& theta, const Eigen::Vector3d& delta) {
  return Pose2(theta.x() + delta.x(), theta.y() + delta.y(), theta.theta() + delta.z());
}

// x - theta in the coordinates of Retract (the angle difference wrapped).
inline Eigen::Vector3d Difference(const Pose2& x, const Pose2& theta) {
  return Eigen::Vector3d(x.x() - theta.x(), x.y() - theta.y(),
                         std::remainder(x.theta() - theta.theta(), 2.0 * M_PI));
}

inline double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

}  // namespace smoother_internal

using smoother_internal::Difference;
using smoother_internal::Retract;
using smoother_internal::Seconds;

class Smoother::Impl {
  using Variable = smoother_internal::Variable;
  using FactorRecord = smoother_internal::FactorRecord;
  using FactorLinearization = smoother_internal::FactorLinearization;
  using TrajectoryInfo = smoother_internal::TrajectoryInfo;

 public:
  explicit Impl(const SmootherOptions& options)
      : options_(options), r_(std::make_shared<SparseR>()) {}

  const SmootherOptions& options() const { return options_; }

  Status AddPose(PoseKey key, const Pose2& initial);
  Status AddBetween(PoseKey from, PoseKey to, const Pose2& z, const Eigen::Matrix3d& cov);
  Status AddEncounter(PoseKey a, PoseKey b, const Pose2& z, const Eigen::Matrix3d& cov);
  UpdateResult Update(bool force_batch, double convergence_step);

  bool Has(const Key& key) const { return index_.count(key) > 0; }
  int NumPoses(TrajectoryId t) const {
    auto it = trajectories_.find(t);
    return it == trajectories_.end() ? 0 : it->second.num_poses;
  }
  const std::vector<TrajectoryId>& trajectory_order() const { return trajectory_order_; }
  Pose2 Estimate(const Key& key) const { return EstimateOf(VarOf(key)); }
  bool HasCovariance(const Key& key) const {
    auto it = index_.find(key);
    return it != index_.end() && vars_[it->second].position >= 0;
  }
  bool GroupChangePending() const {
    if (merge_pending_) return true;
    return std::any_of(pending_vars_.begin(), pending_vars_.end(),
                       [this](int v) { return vars_[v].key.is_anchor(); });
  }
  bool HasPendingChanges() const {
    return merge_pending_ || !pending_vars_.empty() || ActivePending() > 0;
  }
  bool IsAnchored(TrajectoryId t) const {
    auto it = trajectories_.find(t);
    return it != trajectories_.end() && it->second.anchored;
  }
  // Orderings keep trajectory t's newest pose last (with the anchors): always with
  // latest_poses_last, else only while t has no anchor (a lone trajectory adds no clique
  // at R's root, and its next odometry row then enters at R's end).
  bool KeepsLatestPoseLast(TrajectoryId t) const {
    return options_.latest_poses_last || !IsAnchored(t);
  }
  Pose2 GlobalPose(PoseKey key) const {
    const Pose2 local = Estimate(key);
    if (options_.formulation != Formulation::kRelative || !IsAnchored(key.trajectory)) return local;
    return Compose(Estimate(AnchorKey{key.trajectory}), local);
  }
  TrajectoryId GroupRoot(TrajectoryId t) const { return groups_.Contains(t) ? groups_.Root(t) : t; }
  Eigen::MatrixXd JointCovariance(const std::vector<Key>& keys);
  Eigen::Matrix3d ProjectedCovariance(const std::vector<Key>& keys,
                                      const std::vector<Eigen::Matrix3d>& jacobians);
  bool ProjectedCovarianceUntil(const std::vector<Key>& keys,
                                const std::vector<Eigen::Matrix3d>& jacobians,
                                const CovarianceProjection::Enough& enough,
                                Eigen::Matrix3d* covariance) {
    return projected_.ComputeUntil(*r_, SolvedPositions(keys), jacobians, enough, covariance);
  }
  std::vector<Eigen::Matrix3d> ProjectedMarginals(const std::vector<Key>& keys) {
    return projected_.Marginals(*r_, SolvedPositions(keys));
  }
  std::vector<Eigen::Matrix3d> ProjectedCovariances(
      const std::vector<Smoother::CovarianceQuery>& queries) {
    std::vector<CovarianceProjection::Query> solves;
    solves.reserve(queries.size());
    for (const Smoother::CovarianceQuery& query : queries) {
      solves.push_back({SolvedPositions(query.keys), query.jacobians});
    }
    return projected_.ComputeSideBySide(*r_, solves);
  }
  // Positions in R of solved variables; std::invalid_argument for any other.
  std::vector<int> SolvedPositions(const std::vector<Key>& keys) const;
  double Chi2() const;
  const SmootherStats& stats() const { return stats_; }
  CorrectionWork correction_work() const { return {gradient_.passes(), gradient_.linearized()}; }
  Smoother::LinearSystem LinearSystemForTesting() const {
    Smoother::LinearSystem out;
    for (int var : position_to_var_) {
      out.keys.push_back(vars_[var].key);
      out.linearization.push_back(vars_[var].linearization);
    }
    for (int p = 0; p < r_->size(); ++p) out.rows.push_back(r_->row(p));
    out.delta = delta_;
    for (size_t f = 0; f < factors_.size(); ++f) {
      if (!factor_lin_[f].in_r) continue;
      out.factors.push_back(factors_[f].factor);
      out.linearized_at.emplace_back(factor_lin_[f].at.begin(),
                                     factor_lin_[f].at.begin() + factors_[f].num_vars);
    }
    return out;
  }
  SmootherState ExportState() const;
  Status ImportState(SmootherState state);
  std::vector<Factor> ActiveFactors() const {
    std::vector<Factor> out;
    for (const FactorRecord& f : factors_) {
      if (f.active) out.push_back(f.factor);
    }
    return out;
  }

 private:
  Pose2 EstimateOf(int var) const {
    const Variable& v = vars_[var];
    return v.position < 0 ? v.linearization : Retract(v.linearization, OffsetOf(var));
  }
  // Estimate minus linearisation point of a variable in R: delta plus the correction.
  Eigen::Vector3d OffsetOf(int var) const { return delta_[vars_[var].position] + correction_[var]; }
  // The variable of `key`; an unknown key is a caller's bug (HasVariable tells).
  int VarOf(const Key& key) const {
    auto it = index_.find(key);
    if (it == index_.end()) throw std::invalid_argument("unknown variable " + key.ToString());
    return it->second;
  }
  int AddVariable(const Key& key, const Pose2& initial);
  int64_t AddFactor(Factor factor);
  void MarkInR(int64_t id, const std::array<Pose2, kMaxFactorKeys>& at) {
    factor_lin_[id].at = at;
    factor_lin_[id].in_r = true;
    counted_in_gradient_[id] = factors_[id].active ? 1 : 0;
  }
  void TakeOutOfR(int64_t id) {
    factor_lin_[id].in_r = false;
    counted_in_gradient_[id] = 0;
  }
  // counted_in_gradient_ again from factors_ and factor_lin_ (after they were replaced).
  void RecountFactorsInR() {
    counted_in_gradient_.resize(factors_.size());
    for (size_t f = 0; f < factors_.size(); ++f)
      counted_in_gradient_[f] = factors_[f].active && factor_lin_[f].in_r ? 1 : 0;
  }
  Eigen::Matrix3d GaugeSqrtInformation() const {
    return Eigen::Matrix3d::Identity() / options_.gauge_prior_sigma;
  }
  Status CheckMeasurement(const Pose2& z, const Eigen::Matrix3d& covariance) const;
  std::vector<TrajectoryId> GroupMembers(TrajectoryId root) const;
  void MoveTrajectories(const std::vector<TrajectoryId>& trajectories, const Pose2& T_new_old);
  void SetValue(int var, const Pose2& value);

  std::vector<int64_t> GroundPendingFactors(std::vector<char>* grounded) const;
  // `grounded` (grounded_, or a copy of it) brought up to the variables now known, then the
  // pending factors an incremental step would eliminate now (GroundPendingFactors).
  std::vector<int64_t> FactorsReadyForGivens(std::vector<char>* grounded) const;
  void TakeOutOfPending(const std::vector<int64_t>& done);
  // Givens updates of the pending measurements; `solve` false leaves delta as it was
  // (a partial merge step solves after it). False, with nothing changed, when they would
  // add more than `max_fill` non-zeros to R or take more than `max_work` of the rotations'
  // work (SparseR::eliminated_work).
  bool IncrementalStep(bool solve, UpdateResult* result,
                       int64_t max_fill = std::numeric_limits<int64_t>::max(),
                       int64_t max_work = std::numeric_limits<int64_t>::max());
  // IncrementalStep's budget: more fill than R had after its last ordering would make the
  // Givens update dearer than the batch step (whose factorisation is about that size), and
  // R past the fill trigger after it. Eliminating many rows through an ordering that no
  // longer fits the graph can fill R towards dense (minutes, gigabytes), which the trigger
  // (batch_when_fill_grows), tested after the update, is too late to prevent. Below the
  // budget the trigger stays the test: taking every crossing one update early shortened
  // the cycles between fill batch steps (city10000: 94 batch steps instead of 90, 3.5-4 %
  // more CPU).
  int64_t GivensFillBudget() const {
    return options_.batch_when_fill_grows > 0 && nonzeros_after_batch_ > 0
               ? nonzeros_after_batch_
               : std::numeric_limits<int64_t>::max();
  }
  // IncrementalStep's work budget (givens_work_budget): about what the batch step that
  // would reorder R costs, in the rotations' units.
  int64_t GivensWorkBudget() const {
    return options_.batch_when_fill_grows > 0 && options_.givens_work_budget > 0 &&
                   nonzeros_after_batch_ > 0
               ? static_cast<int64_t>(options_.givens_work_budget *
                                      static_cast<double>(nonzeros_after_batch_))
               : std::numeric_limits<int64_t>::max();
  }
  // iSAM2's idea on R: relinearises the variables whose delta exceeds the threshold, and
  // those at `forced` positions, and re-eliminates only the block rows that depend on them
  // (them, the variables they share factors with, and their ancestors in the elimination
  // tree), locally reordered; factors no longer active leave R on the way. `full_solve`
  // back-substitutes all of R afterwards. All or nothing: false (result->status) leaves
  // the smoother as it was. True without work when nothing drifted and nothing is forced.
  // False with result->status ok, nothing changed, when it would re-eliminate more than
  // `max_rows` block rows.
  bool PartialRelinearization(const std::vector<int>& forced, bool full_solve, UpdateResult* result,
                              bool keep_estimate = false,
                              int max_rows = std::numeric_limits<int>::max());
  // Two anchored groups joined (relative formulation, partial_merges): the new
  // measurements by Givens updates, then a partial step over the moved anchors and the
  // one whose gauge prior was dropped. Falls back to a batch step if that fails.
  void PartialMergeStep(UpdateResult* result);
  // correction_tolerance: moves the estimate toward the nonlinear optimum with R as the
  // preconditioner; false if it did not converge in correction_iterations steps.
  bool CorrectEstimate();
  // Kept-estimate mode's skip test: whether the decrease a correction would predict now
  // is surely at most `budget` (innovation_ and the uncorrected factors' errors).
  bool UncorrectedDecreaseWithin(double budget);
  // correction_local_hops: Gauss-Newton on the variables near the uncorrected factors
  // (the rest fixed); true when afterwards the decrease a global correction would bring is
  // surely within `budget` (else the caller corrects globally from there).
  bool CorrectLocally(double budget);
  // A variable's value at the last gradient pass (its estimate unless a local correction
  // moved it since), and forgetting those moves (a pass took them in).
  Pose2 PassValueOf(int var) const;
  void ForgetLocalMoves();
  // Gauss-Newton on `region` (variables in R's order) with every other variable fixed;
  // `seen` are the counted factors on it. False if its normal equations are singular.
  bool SolveRegion(const std::vector<int>& region, const std::vector<int64_t>& seen);
  bool CorrectByFixedPointSteps();
  bool CorrectByConjugateGradients();
  // A new variable of `f` (position >= first_new) with no correction yet gets the one its
  // neighbours' corrections imply through the factor's Jacobians `lin`.
  void PlaceByNeighboursCorrection(const FactorRecord& f, const LinearizedFactor& lin,
                                   int first_new);
  // chi2 at the estimate over the factors in R; its half-gradient g by position in R is
  // gradient_.g(), and gradient_.MultiplyNormal() applies J^T J there. Only what
  // the estimate's moves since the last pass changed is computed again, with the bits a
  // full pass gives (incremental_gradient.h).
  double GradientAtEstimate();
  // The drift check: a partial step (or a batch step) on the variables whose estimate
  // moved more than relinearize_threshold from their linearisation point; false if none.
  // A partial step that would re-eliminate more than `max_partial_rows` block rows is a
  // batch step instead.
  bool RelinearizeDrifted(UpdateResult* result,
                          int max_partial_rows = std::numeric_limits<int>::max());
  // After a correction that stalled: relinearise and correct again, up to three times.
  void RelinearizeUntilCorrected(UpdateResult* result);
  // correction_cg_iterations: R only preconditions the correction; the estimate moves only
  // by correction steps (and batch steps), not when R's solution changes (new rows, partial
  // steps), because a stale R's linear model moves it the wrong way.
  bool KeepsEstimate() const {
    return options_.correction_tolerance > 0 && options_.correction_cg_iterations > 0;
  }
  // How far above correction_tolerance an update may stay uncorrected (CG mode only).
  double SkipFactor() const {
    return options_.correction_cg_iterations > 0 ? options_.correction_skip_factor : 1.0;
  }
  int LocalHops() const { return KeepsEstimate() ? options_.correction_local_hops : 0; }
  // Kept-estimate mode, after IncrementalStep's Givens updates (no back-substitution):
  // each new variable (position >= first_new) is placed by the factor that determines it
  // (`jacobians`, by factor of `ready`) relative to its neighbours' estimates, as R's
  // solution places it relative to theirs.
  void PlaceNewVariables(const std::vector<int64_t>& ready,
                         const std::vector<LinearizedFactor>& jacobians, int first_new);
  // Sets the correction so that every variable in R is at `estimate` (by variable).
  void KeepEstimate(const std::vector<Pose2>& estimate);
  bool MergesByPartialStep() const {
    return options_.partial_merges && options_.formulation == Formulation::kRelative;
  }
  // Relinearises, reorders and refactors; iterates until the step is below `tolerance`
  // (or once unless `converge`); counts itself in stats_. All or nothing: on failure
  // (result->status) the smoother is as it was before the call.
  void BatchStep(bool converge, double tolerance, UpdateResult* result);
  // What a batch step changes, for putting it back when the step fails. R is shared,
  // not copied (MutableR copies on write while a snapshot holds it).
  struct Snapshot {
    std::vector<Variable> vars;
    std::vector<FactorLinearization> factor_lin;
    std::vector<int64_t> pending_factors;
    std::vector<int> pending_vars;
    std::vector<char> grounded;
    std::vector<int> position_to_var;
    std::vector<Eigen::Vector3d> delta;
    std::vector<Eigen::Vector3d> correction;
    std::shared_ptr<SparseR> r;
    int updates_since_batch;
    int64_t nonzeros_after_batch;
  };
  Snapshot Save() const {
    return {vars_,
            factor_lin_,
            pending_factors_,
            pending_vars_,
            grounded_,
            position_to_var_,
            delta_,
            correction_,
            r_,
            updates_since_batch_,
            nonzeros_after_batch_};
  }
  void Restore(Snapshot&& s) {
    vars_ = std::move(s.vars);
    factor_lin_ = std::move(s.factor_lin);
    pending_factors_ = std::move(s.pending_factors);
    pending_vars_ = std::move(s.pending_vars);
    grounded_ = std::move(s.grounded);
    position_to_var_ = std::move(s.position_to_var);
    delta_ = std::move(s.delta);
    correction_ = std::move(s.correction);
    r_ = std::move(s.r);
    RecountFactorsInR();
    updates_since_batch_ = s.updates_since_batch;
    nonzeros_after_batch_ = s.nonzeros_after_batch;
  }
  void GaussNewtonIterations(const std::vector<int64_t>& included, int max_iterations,
                             UpdateResult* result);
  void DogLegIterations(const std::vector<int64_t>& included, int max_iterations,
                        UpdateResult* result);
  // Linearises `included` at the linearisation point, factors them in the current order
  // and solves for delta; false (with result->status) on failure. If given, `chi2` at the
  // linearisation point and the decrease the Gauss-Newton model predicts (|d|^2).
  bool FactorAll(const std::vector<int64_t>& included, UpdateResult* result, double* chi2 = nullptr,
                 double* predicted_decrease = nullptr);
  // Halves delta while the Gauss-Newton step (chi2 at it: step_chi2) raised chi2 by more
  // than it predicted to lower it (smoother_nonlinear.cc: why); the next iteration
  // relinearises there.
  void ShortenOvershootingStep(const std::vector<int64_t>& included, double chi2,
                               double predicted_decrease, double step_chi2);
  // Kept-estimate mode's form of the above, for every iteration including the last: delta
  // stays R's solution and the correction takes back what the estimate does not move. True
  // when the batch step ends here (a shortened last step, or one that buys less than the
  // correction's tolerance).
  bool ShortenInTheCorrection(const std::vector<int64_t>& included, double chi2,
                              double predicted_decrease, bool last);
  // The power of two (halving up to 20 times) that scales delta to a step that does not
  // raise chi2 above `chi2`; `step_chi2` holds chi2 at the full step on entry, at the scaled
  // one on return. delta is left as it is.
  double ScaleThatDoesNotRaiseChi2(const std::vector<int64_t>& included, double chi2,
                                   double* step_chi2);
  // chi2 at linearisation point + step (step empty: at the linearisation point).
  double Chi2Of(const std::vector<int64_t>& included,
                const std::vector<Eigen::Vector3d>& step) const;
  int CountAnchors() const;
  void CountBatchStep(StepKind kind, UpdateResult* result);
  int ActivePending() const {
    int n = 0;
    for (int64_t f : pending_factors_) n += factors_[f].active ? 1 : 0;
    return n;
  }
  static double MaxAbs(const std::vector<Eigen::Vector3d>& v);
  // How far a variable is from its linearisation point, for relinearize_threshold.
  static double Drift(const Eigen::Vector3d& d) { return d.cwiseAbs().maxCoeff(); }
  // Positions (ascending) of the variables whose delta exceeds relinearize_threshold,
  // and the largest drift seen.
  std::vector<int> DriftedPositions(double* max_drift) const;
  SparseR& MutableR() {
    if (r_.use_count() > 1) r_ = std::make_shared<SparseR>(*r_);  // a snapshot holds the old one
    return *r_;
  }
  // For replacing R as a whole: no copy of the old one.
  SparseR& FreshR() {
    if (r_.use_count() > 1) r_ = std::make_shared<SparseR>();
    return *r_;
  }

  SmootherOptions options_;
  std::vector<Variable> vars_;
  std::unordered_map<Key, int, KeyHash> index_;
  std::vector<FactorRecord> factors_;
  std::vector<FactorLinearization> factor_lin_;  // by factor id
  // By factor id: active and its rows in R (what the gradient passes count), kept in step
  // with factors_ and factor_lin_ so that a pass need not read them all.
  std::vector<char> counted_in_gradient_;
  std::vector<std::vector<int64_t>> var_factors_;  // by variable: ids of its factors
  std::vector<int64_t> factor_stamp_;              // PartialRelinearization's work space
  std::vector<Eigen::Vector3d> tail_solution_;     // PlaceNewVariables' work space
  int64_t stamp_ = 0;
  std::vector<int64_t> pending_factors_;
  std::vector<int> pending_vars_;
  std::vector<char> grounded_;  // IncrementalStep's view of which variables are in R
  std::vector<int> position_to_var_;
  std::vector<Eigen::Vector3d> delta_;  // by position
  // By variable: the estimate is linearization + delta + correction (correction_tolerance;
  // zero otherwise and for variables not in R).
  std::vector<Eigen::Vector3d> correction_;
  bool correction_converged_ = false;  // the last CorrectEstimate() converged
  double last_chi2_ = 0.0;             // chi2 at its last gradient evaluation
  // The skip test's estimate of the decrease a correction would bring: CG mode, the decrease
  // the last correction still predicted (UncorrectedDecreaseWithin adds the factors since);
  // else the new factors' chi2 at entry and after the update since it.
  double innovation_ = 0.0;
  // Kept-estimate mode: the factors that entered R since the last correction ran.
  std::vector<int64_t> uncorrected_factors_;
  double last_decrease_ = 0.0;  // CG: the decrease predicted at the last gradient pass
  // Work space of GradientAtEstimate (not in the state: a function of the estimate).
  IncrementalGradient gradient_;
  std::vector<Pose2> estimate_scratch_;
  FlatR flat_r_;  // the correction's copy of R (not in the state: rebuilt from r_)
  // The skip test's work space.
  PathSolve path_solve_;
  std::vector<std::pair<int, Eigen::Vector3d>> new_gradient_;
  // CorrectLocally's work space, by variable (-1: outside the region) and by factor id.
  std::vector<int> local_index_;
  std::vector<char> local_factor_;
  size_t local_seeds_from_ = 0;  // uncorrected_factors_ from here on entered since
  // Variables local corrections moved since the last pass, with their value there, and
  // the factors that pass counted which see them (sorted).
  std::vector<std::pair<int, Pose2>> pass_values_;
  std::vector<int> pass_index_;  // by variable: into pass_values_, -1 if not moved
  std::vector<int64_t> moved_factors_;
  std::shared_ptr<SparseR> r_;
  std::unique_ptr<CovarianceRecovery> covariances_;
  CovarianceProjection projected_;  // work space, and the memo of one R revision's queries
  BatchFactorization batch_;
  AnchorGroups groups_;
  std::unordered_map<TrajectoryId, TrajectoryInfo> trajectories_;
  std::vector<TrajectoryId> trajectory_order_;
  bool merge_pending_ = false;
  // Variables a pending partial merge must relinearise: moved anchors, the anchor whose
  // gauge prior was dropped.
  std::vector<int> merge_vars_;
  double tolerance_ = 0.0;  // convergence step of the running batch step
  int updates_since_batch_ = 0;
  std::vector<Eigen::Vector3d> step_scratch_;  // ScaleThatDoesNotRaiseChi2's halved step
  int updates_since_drift_check_ = 0;
  int64_t nonzeros_after_batch_ = 0;
  SmootherStats stats_;
};

}  // namespace anchormap
