#include "common/solver/smoother.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <unordered_map>

#include <Eigen/Dense>

#include "common/geometry/covariance.h"
#include "common/solver/anchor_groups.h"
#include "common/solver/batch_factorization.h"
#include "common/solver/covariances.h"
#include "common/solver/factor.h"
#include "common/solver/ordering.h"
#include "common/solver/sparse_r.h"

namespace anchormap {
namespace {

// The system is linearised at `linearization` (theta); R delta = d gives the current
// solution delta relative to it (additive in x, y, theta, as iSAM's Pose2d).
struct Variable {
  Key key;
  Pose2 linearization;
  int position = -1;  // elimination position; -1 while pending (not yet in R)
};

struct FactorRecord {
  Factor factor;
  std::array<int, kMaxFactorKeys> vars{};
  int num_vars = 0;
  bool active = true;  // false once removed (a gauge prior dropped at a merge)
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

Pose2 Retract(const Pose2& theta, const Eigen::Vector3d& delta) {
  return Pose2(theta.x() + delta.x(), theta.y() + delta.y(), theta.theta() + delta.z());
}

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

}  // namespace

class Smoother::Impl {
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
  bool IsAnchored(TrajectoryId t) const {
    auto it = trajectories_.find(t);
    return it != trajectories_.end() && it->second.anchored;
  }
  Pose2 GlobalPose(PoseKey key) const {
    const Pose2 local = Estimate(key);
    if (options_.formulation != Formulation::kRelative || !IsAnchored(key.trajectory)) return local;
    return Compose(Estimate(AnchorKey{key.trajectory}), local);
  }
  TrajectoryId GroupRoot(TrajectoryId t) const { return groups_.Contains(t) ? groups_.Root(t) : t; }
  Eigen::MatrixXd JointCovariance(const std::vector<Key>& keys);
  double Chi2() const;
  const SmootherStats& stats() const { return stats_; }
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
    return v.position < 0 ? v.linearization : Retract(v.linearization, delta_[v.position]);
  }
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
  }
  Eigen::Matrix3d GaugeSqrtInformation() const {
    return Eigen::Matrix3d::Identity() / options_.gauge_prior_sigma;
  }
  Status CheckMeasurement(const Pose2& z, const Eigen::Matrix3d& covariance) const;
  std::vector<TrajectoryId> GroupMembers(TrajectoryId root) const;
  void MoveTrajectories(const std::vector<TrajectoryId>& trajectories, const Pose2& T_new_old);
  void SetValue(int var, const Pose2& value);

  std::vector<int64_t> GroundPendingFactors(std::vector<char>* grounded) const;
  void TakeOutOfPending(const std::vector<int64_t>& done);
  void IncrementalStep(UpdateResult* result);
  // iSAM2's idea on R: relinearises the variables whose delta exceeds the threshold and
  // re-eliminates only the block rows that depend on them (them, the variables they share
  // factors with, and their ancestors in the elimination tree), locally reordered. All or
  // nothing: false (result->status) leaves the smoother as it was.
  bool PartialRelinearization(UpdateResult* result);
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
    r_ = std::move(s.r);
    updates_since_batch_ = s.updates_since_batch;
    nonzeros_after_batch_ = s.nonzeros_after_batch;
  }
  void GaussNewtonIterations(const std::vector<int64_t>& included, int max_iterations,
                             UpdateResult* result);
  void DogLegIterations(const std::vector<int64_t>& included, int max_iterations,
                        UpdateResult* result);
  // Linearises `included` at the linearisation point, factors them in the current order
  // and solves for delta; false (with result->status) on failure.
  bool FactorAll(const std::vector<int64_t>& included, UpdateResult* result);
  // chi2 at linearisation point + step (step empty: at the linearisation point).
  double Chi2Of(const std::vector<int64_t>& included,
                const std::vector<Eigen::Vector3d>& step) const;
  int CountAnchors() const;
  int ActivePending() const {
    int n = 0;
    for (int64_t f : pending_factors_) n += factors_[f].active ? 1 : 0;
    return n;
  }
  static double MaxAbs(const std::vector<Eigen::Vector3d>& v);
  // How far a variable is from its linearisation point, for relinearize_threshold.
  static double Drift(const Eigen::Vector3d& d) { return d.cwiseAbs().maxCoeff(); }
  double MaxDrift() const {
    double m = 0.0;
    for (const auto& d : delta_) m = std::max(m, Drift(d));
    return m;
  }
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
  std::vector<FactorLinearization> factor_lin_;    // by factor id
  std::vector<std::vector<int64_t>> var_factors_;  // by variable: ids of its factors
  std::vector<int64_t> factor_stamp_;              // PartialRelinearization's work space
  int64_t stamp_ = 0;
  std::vector<int64_t> pending_factors_;
  std::vector<int> pending_vars_;
  std::vector<char> grounded_;  // IncrementalStep's view of which variables are in R
  std::vector<int> position_to_var_;
  std::vector<Eigen::Vector3d> delta_;  // by position
  std::shared_ptr<SparseR> r_;
  std::unique_ptr<CovarianceRecovery> covariances_;
  BatchFactorization batch_;
  AnchorGroups groups_;
  std::unordered_map<TrajectoryId, TrajectoryInfo> trajectories_;
  std::vector<TrajectoryId> trajectory_order_;
  bool merge_pending_ = false;
  double tolerance_ = 0.0;  // convergence step of the running batch step
  int updates_since_batch_ = 0;
  int updates_since_drift_check_ = 0;
  int64_t nonzeros_after_batch_ = 0;
  SmootherStats stats_;
};

int Smoother::Impl::AddVariable(const Key& key, const Pose2& initial) {
  const int var = static_cast<int>(vars_.size());
  vars_.push_back({key, initial, -1});
  var_factors_.emplace_back();
  index_.emplace(key, var);
  pending_vars_.push_back(var);
  ++stats_.variables;
  return var;
}

int64_t Smoother::Impl::AddFactor(Factor factor) {
  FactorRecord record{std::move(factor), {}, 0, true};
  for (const Key& key : FactorKeys(record.factor)) record.vars[record.num_vars++] = index_.at(key);
  const int64_t id = static_cast<int64_t>(factors_.size());
  for (int j = 0; j < record.num_vars; ++j) {
    std::vector<int64_t>& list = var_factors_[record.vars[j]];
    if (list.empty() || list.back() != id) list.push_back(id);
  }
  factors_.push_back(std::move(record));
  factor_lin_.emplace_back();
  pending_factors_.push_back(static_cast<int64_t>(factors_.size()) - 1);
  ++stats_.factors;
  return static_cast<int64_t>(factors_.size()) - 1;
}

void Smoother::Impl::SetValue(int var, const Pose2& value) {
  // Only used right before a batch step, which relinearises everything.
  vars_[var].linearization = value;
  if (vars_[var].position >= 0) delta_[vars_[var].position].setZero();
}

Status Smoother::Impl::CheckMeasurement(const Pose2& z, const Eigen::Matrix3d& covariance) const {
  if (!z.IsFinite()) return Status::Error("measurement is not finite");
  if (auto problem = CheckSymmetricPositiveDefinite(covariance)) {
    return Status::Error("covariance rejected: " + *problem);
  }
  return Status::Ok();
}

Status Smoother::Impl::AddPose(PoseKey key, const Pose2& initial) {
  if (key.index < 0) return Status::Error("pose index must be >= 0");
  if (!initial.IsFinite()) return Status::Error("initial pose is not finite");
  if (Has(key)) return Status::Error("pose " + Key(key).ToString() + " exists already");
  auto it = trajectories_.find(key.trajectory);
  if (it == trajectories_.end()) {
    if (key.index != 0) {
      return Status::Error("trajectory " + std::to_string(key.trajectory) +
                           " must start with pose index 0");
    }
    AddVariable(key, initial);
    TrajectoryInfo info;
    info.num_poses = 1;
    info.origin_prior = AddFactor(PriorFactor{key, initial, GaugeSqrtInformation()});
    if (options_.formulation != Formulation::kRelative) {
      groups_.CreateGroup(key.trajectory, info.origin_prior);
    }
    trajectories_.emplace(key.trajectory, info);
    trajectory_order_.push_back(key.trajectory);
    return Status::Ok();
  }
  AddVariable(key, initial);
  it->second.max_index = std::max(it->second.max_index, key.index);
  ++it->second.num_poses;
  return Status::Ok();
}

Status Smoother::Impl::AddBetween(PoseKey from, PoseKey to, const Pose2& z,
                                  const Eigen::Matrix3d& covariance) {
  if (!Has(from) || !Has(to)) return Status::Error("between factor on an unknown pose");
  if (from.trajectory != to.trajectory) {
    return Status::Error("between factor joins two trajectories: use AddEncounter");
  }
  if (from == to) return Status::Error("between factor from a pose to itself");
  if (Status s = CheckMeasurement(z, covariance); !s.ok()) return s;
  AddFactor(BetweenFactor{from, to, z, SqrtInformationFromCovariance(covariance)});
  return Status::Ok();
}

std::vector<TrajectoryId> Smoother::Impl::GroupMembers(TrajectoryId root) const {
  std::vector<TrajectoryId> members;
  for (TrajectoryId t : trajectory_order_) {
    if (groups_.Contains(t) && groups_.Root(t) == root) members.push_back(t);
  }
  return members;
}

void Smoother::Impl::MoveTrajectories(const std::vector<TrajectoryId>& trajectories,
                                      const Pose2& T_new_old) {
  for (TrajectoryId t : trajectories) {
    if (options_.formulation == Formulation::kRelative) {
      const int var = index_.at(AnchorKey{t});
      SetValue(var, Compose(T_new_old, EstimateOf(var)));
      continue;
    }
    for (int var = 0; var < static_cast<int>(vars_.size()); ++var) {
      if (vars_[var].key.trajectory == t && !vars_[var].key.is_anchor()) {
        SetValue(var, Compose(T_new_old, EstimateOf(var)));
      }
    }
  }
}

Status Smoother::Impl::AddEncounter(PoseKey a, PoseKey b, const Pose2& z,
                                    const Eigen::Matrix3d& covariance) {
  if (!Has(a) || !Has(b)) return Status::Error("encounter on an unknown pose");
  if (a.trajectory == b.trajectory) {
    return Status::Error("encounter within one trajectory: use AddBetween (a loop closure)");
  }
  if (Status s = CheckMeasurement(z, covariance); !s.ok()) return s;
  const Eigen::Matrix3d sqrt_information = SqrtInformationFromCovariance(covariance);

  if (options_.formulation == Formulation::kRelative) {
    TrajectoryInfo& info_a = trajectories_.at(a.trajectory);
    TrajectoryInfo& info_b = trajectories_.at(b.trajectory);
    const Pose2 x_a = Estimate(a), x_b = Estimate(b);
    if (!info_a.anchored && !info_b.anchored) {
      // First encounter of both: a's local frame becomes its group's frame.
      const int anchor = AddVariable(AnchorKey{a.trajectory}, Pose2());
      info_a.anchored = true;
      groups_.CreateGroup(
          a.trajectory, AddFactor(PriorFactor{vars_[anchor].key, Pose2(), GaugeSqrtInformation()}));
    }
    if (!info_b.anchored) {
      // T_global_local_b such that A_b (+) x_b = A_a (+) x_a (+) z: only anchors move.
      const Pose2 A_a = Estimate(AnchorKey{a.trajectory});
      AddVariable(AnchorKey{b.trajectory}, Compose(Compose(Compose(A_a, x_a), z), x_b.Inverse()));
      info_b.anchored = true;
      groups_.Join(b.trajectory, a.trajectory);
    } else if (!info_a.anchored) {
      const Pose2 A_b = Estimate(AnchorKey{b.trajectory});
      AddVariable(AnchorKey{a.trajectory},
                  Compose(Compose(Compose(A_b, x_b), z.Inverse()), x_a.Inverse()));
      info_a.anchored = true;
      groups_.Join(a.trajectory, b.trajectory);
    }
  }

  if (!groups_.SameGroup(a.trajectory, b.trajectory)) {
    // Two groups, each with its own gauge, join: keep the older gauge, drop the other's
    // prior (removing rows needs a batch step), and move the absorbed group rigidly so
    // that it agrees with this encounter (only its anchors in the relative formulation;
    // every pose in global-moved; nothing in the thesis' global baseline).
    const TrajectoryId root_a = groups_.Root(a.trajectory);
    const TrajectoryId root_b = groups_.Root(b.trajectory);
    const std::vector<TrajectoryId> members_a = GroupMembers(root_a);
    const std::vector<TrajectoryId> members_b = GroupMembers(root_b);
    const AnchorGroups::Merge merge = groups_.MergeGroups(a.trajectory, b.trajectory);
    factors_[merge.absorbed_prior_id].active = false;
    merge_pending_ = true;
    if (options_.formulation != Formulation::kGlobal) {
      const bool a_absorbed = merge.absorbed_root == root_a;
      const Pose2 global_a = GlobalPose(a), global_b = GlobalPose(b);
      const Pose2 T_new_old = a_absorbed
                                  ? Compose(Compose(global_b, z.Inverse()), global_a.Inverse())
                                  : Compose(Compose(global_a, z), global_b.Inverse());
      MoveTrajectories(a_absorbed ? members_a : members_b, T_new_old);
    }
  }

  if (options_.formulation == Formulation::kRelative) {
    AddFactor(EncounterFactor{a, b, z, sqrt_information});
  } else {
    AddFactor(GlobalEncounterFactor{a, b, z, sqrt_information});
  }
  return Status::Ok();
}

// --- Updates ---------------------------------------------------------------------------

std::vector<int64_t> Smoother::Impl::GroundPendingFactors(std::vector<char>* grounded) const {
  // A measurement enters R only when all but at most one of its variables are already
  // determined; it then determines the last one (every factor's Jacobian block is
  // invertible). Anything else waits, so R never gets a singular diagonal block.
  std::vector<int64_t> ready;
  std::vector<char> used(pending_factors_.size(), 0);
  bool progress = true;
  while (progress) {
    progress = false;
    for (size_t k = 0; k < pending_factors_.size(); ++k) {
      if (used[k]) continue;
      const FactorRecord& f = factors_[pending_factors_[k]];
      if (!f.active) {
        used[k] = 1;
        continue;
      }
      int unknown = -1, unknowns = 0;
      for (int j = 0; j < f.num_vars; ++j) {
        if (!(*grounded)[f.vars[j]]) {
          unknown = f.vars[j];
          ++unknowns;
        }
      }
      if (unknowns > 1) continue;
      if (unknown >= 0) (*grounded)[unknown] = 1;
      used[k] = 1;
      ready.push_back(pending_factors_[k]);
      progress = true;
    }
  }
  return ready;
}

void Smoother::Impl::TakeOutOfPending(const std::vector<int64_t>& done) {
  // O(pending + done log done), not O(all factors): this runs after every update.
  std::vector<int64_t> sorted_done = done;
  std::sort(sorted_done.begin(), sorted_done.end());
  std::vector<int64_t> still;
  for (int64_t f : pending_factors_) {
    if (!std::binary_search(sorted_done.begin(), sorted_done.end(), f) && factors_[f].active) {
      still.push_back(f);
    }
  }
  pending_factors_.swap(still);
  std::vector<int> vars;
  for (int v : pending_vars_) {
    if (vars_[v].position < 0) vars.push_back(v);
  }
  pending_vars_.swap(vars);
}

void Smoother::Impl::IncrementalStep(UpdateResult* result) {
  // grounded[v] == (v is in R), kept between updates so that an update costs what it
  // touches: only new and pending variables need a fresh look (a batch step clears it).
  std::vector<char>& grounded = grounded_;
  const size_t known = grounded.size();
  grounded.resize(vars_.size());
  for (size_t v = known; v < vars_.size(); ++v) grounded[v] = vars_[v].position >= 0;
  for (int v : pending_vars_) grounded[v] = vars_[v].position >= 0;
  const std::vector<int64_t> ready = GroundPendingFactors(&grounded);

  SparseR& R = MutableR();
  int appended = 0;
  for (int v : pending_vars_) {
    if (!grounded[v]) continue;
    vars_[v].position = R.size() + appended++;
    position_to_var_.push_back(v);
  }
  R.Append(appended);
  delta_.resize(R.size(), Eigen::Vector3d::Zero());

  std::vector<int> touched;
  std::array<Pose2, kMaxFactorKeys> values;
  std::vector<NewRows> new_rows;
  new_rows.reserve(ready.size());
  for (int64_t id : ready) {
    const FactorRecord& f = factors_[id];
    for (int j = 0; j < f.num_vars; ++j) values[j] = EstimateOf(f.vars[j]);
    // Linearised at the current estimate, expressed relative to the linearisation point
    // of R: J (x - theta) = -e(x_hat) + J delta.
    const LinearizedFactor lin = Linearize(f.factor, values.data());
    MarkInR(id, values);
    NewRows rows;
    rows.rhs = -lin.whitened_error;
    for (int j = 0; j < f.num_vars; ++j) {
      const int position = vars_[f.vars[j]].position;
      rows.blocks.emplace_back(position, lin.jacobians[j]);
      rows.rhs += lin.jacobians[j] * delta_[position];
    }
    new_rows.push_back(std::move(rows));
  }
  // All at once: their paths up R share the rows near the root.
  R.Eliminate(std::move(new_rows), &touched);
  TakeOutOfPending(ready);

  if (options_.backsubstitution_threshold == 0.0) {
    R.BackSubstitute(&delta_);
    result->rows_backsubstituted = R.size();
  } else {
    result->rows_backsubstituted =
        R.BackSubstitutePartial(touched, options_.backsubstitution_threshold, &delta_);
  }
}

bool Smoother::Impl::PartialRelinearization(UpdateResult* result) {
  const auto start = std::chrono::steady_clock::now();
  const int n = r_->size();
  const double threshold = options_.relinearize_threshold;
  // 1. The drifted variables S (by position) and their new linearisation points.
  std::vector<char> drifted(n, 0), in_b(n, 0);
  std::vector<int> drifted_positions;
  for (int p = 0; p < n; ++p) {
    if (Drift(delta_[p]) > threshold) {
      drifted[p] = 1;
      drifted_positions.push_back(p);
    }
  }
  if (drifted_positions.empty()) return true;
  auto theta = [&](int var) {  // the new linearisation point
    const Variable& v = vars_[var];
    return drifted[v.position] ? Retract(v.linearization, delta_[v.position]) : v.linearization;
  };
  auto usable = [&](int64_t f) { return factors_[f].active && factor_lin_[f].in_r; };
  // 2. Affected: S, every variable that shares a factor with S (those factors are
  // relinearised), each trajectory's latest pose and the anchors (kept at the end for
  // the next Givens updates), then every ancestor in the elimination tree, so that no
  // row of B references a row outside it.
  for (int p : drifted_positions) {
    in_b[p] = 1;
    for (int64_t f : var_factors_[position_to_var_[p]]) {
      if (!usable(f)) continue;
      for (int j = 0; j < factors_[f].num_vars; ++j) in_b[vars_[factors_[f].vars[j]].position] = 1;
    }
  }
  auto is_keep_last = [&](int var) {
    const Key& key = vars_[var].key;
    if (key.is_anchor()) return true;
    auto it = trajectories_.find(key.trajectory);
    return it != trajectories_.end() && it->second.max_index == key.index;
  };
  for (const auto& [t, info] : trajectories_) {
    for (const Key& key : {Key(PoseKey{t, info.max_index}), Key(AnchorKey{t})}) {
      auto it = index_.find(key);
      if (it != index_.end() && vars_[it->second].position >= 0) {
        in_b[vars_[it->second].position] = 1;
      }
    }
  }
  // (Every block of row p is an ancestor of p; marking them all, not only the parent,
  // keeps B closed even where an exact zero dropped a fill-in block.)
  int p0 = n;
  for (int p = 0; p < n; ++p) {
    if (!in_b[p]) continue;
    p0 = std::min(p0, p);
    for (const auto& entry : r_->row(p).right) in_b[entry.first] = 1;
  }
  std::vector<int> b_positions, kept;  // B ascending; the tail's other rows
  std::vector<int> local(n - p0, -1);  // old position -> index in B
  for (int p = p0; p < n; ++p) {
    if (in_b[p]) {
      local[p - p0] = static_cast<int>(b_positions.size());
      b_positions.push_back(p);
    } else {
      kept.push_back(p);
    }
  }
  const int nb = static_cast<int>(b_positions.size());

  // 3. Factors with a variable in B (relinearised if they touch S), and the rows outside
  // B that reference B (their part in B is subtracted: R_BB^T R_BB = H_BB - R_FB^T R_FB).
  if (factor_stamp_.size() < factors_.size()) factor_stamp_.resize(factors_.size(), 0);
  ++stamp_;
  struct LocalFactor {
    int64_t id;
    bool relinearize;
  };
  std::vector<LocalFactor> local_factors;
  for (int p : b_positions) {
    for (int64_t f : var_factors_[position_to_var_[p]]) {
      if (!usable(f) || factor_stamp_[f] == stamp_) continue;
      factor_stamp_[f] = stamp_;
      bool touches_s = false;
      for (int j = 0; j < factors_[f].num_vars; ++j) {
        touches_s = touches_s || drifted[vars_[factors_[f].vars[j]].position];
      }
      local_factors.push_back({f, touches_s});
    }
  }
  std::vector<int> boundary;  // rows outside B with a block in B
  {
    std::vector<char> seen(n, 0);
    for (int p : b_positions) {
      for (int r : r_->RowsReferencing(p)) {
        if (!in_b[r] && !seen[r]) {
          seen[r] = 1;
          boundary.push_back(r);
        }
      }
    }
  }
  // Their right-hand sides in the new coordinates: d_r - sum over S of R_rq (theta'_q - theta_q).
  std::vector<std::pair<int, Eigen::Vector3d>> boundary_rhs;
  boundary_rhs.reserve(boundary.size());
  for (int r : boundary) {
    Eigen::Vector3d d = r_->row(r).rhs;
    for (const auto& [q, block] : r_->row(r).right) {
      if (drifted[q]) d.noalias() -= block * delta_[q];
    }
    boundary_rhs.emplace_back(r, d);
  }

  // 4. Local ordering of B (CCOLAMD, the same constraints as a batch step).
  std::vector<std::vector<int>> structure;
  structure.reserve(local_factors.size() + boundary.size());
  for (const LocalFactor& lf : local_factors) {
    std::vector<int> vars;
    for (int j = 0; j < factors_[lf.id].num_vars; ++j) {
      const int p = vars_[factors_[lf.id].vars[j]].position;
      if (in_b[p]) vars.push_back(local[p - p0]);
    }
    structure.push_back(std::move(vars));
  }
  for (int r : boundary) {
    std::vector<int> vars;
    for (const auto& [q, block] : r_->row(r).right) {
      if (q >= p0 && in_b[q]) vars.push_back(local[q - p0]);
    }
    structure.push_back(std::move(vars));
  }
  std::vector<bool> keep_last(nb);
  for (int k = 0; k < nb; ++k) keep_last[k] = is_keep_last(position_to_var_[b_positions[k]]);
  Result<std::vector<int>> ordering = ComputeOrdering(nb, structure, keep_last);
  if (!ordering.ok()) {
    result->status = ordering.status();
    return false;
  }
  std::vector<int> order_of(nb);  // B index -> new local position
  for (int k = 0; k < nb; ++k) order_of[(*ordering)[k]] = k;

  // 5. Normal equations of B in the new order, minus the boundary rows' part; factor.
  std::vector<std::vector<std::pair<int, Eigen::Matrix3d>>> columns(nb);
  std::vector<Eigen::Vector3d> gradient(nb, Eigen::Vector3d::Zero());
  auto add_row_block = [&](int a, int b, const Eigen::Matrix3d& block) {  // H_ab, a <= b
    columns[b].emplace_back(a, block);
  };
  std::vector<std::array<Pose2, kMaxFactorKeys>> relinearized_at;
  std::array<Pose2, kMaxFactorKeys> at;
  std::array<int, kMaxFactorKeys> slot;
  for (const LocalFactor& lf : local_factors) {
    const FactorRecord& f = factors_[lf.id];
    if (lf.relinearize) {
      for (int j = 0; j < f.num_vars; ++j) at[j] = theta(f.vars[j]);
      relinearized_at.push_back(at);
    } else {
      at = factor_lin_[lf.id].at;
    }
    const LinearizedFactor lin = Linearize(f.factor, at.data());
    Eigen::Vector3d rhs = -lin.whitened_error;
    for (int j = 0; j < f.num_vars; ++j) {
      const Pose2 point = theta(f.vars[j]);
      const Eigen::Vector3d offset(at[j].x() - point.x(), at[j].y() - point.y(),
                                   std::remainder(at[j].theta() - point.theta(), 2.0 * M_PI));
      rhs.noalias() += lin.jacobians[j] * offset;
      const int p = vars_[f.vars[j]].position;
      slot[j] = in_b[p] ? order_of[local[p - p0]] : -1;
    }
    for (int a = 0; a < f.num_vars; ++a) {
      if (slot[a] < 0) continue;
      gradient[slot[a]].noalias() += lin.jacobians[a].transpose() * rhs;
      for (int b = 0; b < f.num_vars; ++b) {
        if (slot[b] < 0 || slot[a] > slot[b] || (slot[a] == slot[b] && a > b)) continue;
        Eigen::Matrix3d block = lin.jacobians[a].transpose() * lin.jacobians[b];
        if (slot[a] == slot[b] && a != b) block += block.transpose().eval();
        add_row_block(slot[a], slot[b], block);
      }
    }
  }
  std::vector<std::pair<int, const Eigen::Matrix3d*>> part;
  for (size_t k = 0; k < boundary.size(); ++k) {
    const RBlockRow& row = r_->row(boundary[k]);
    part.clear();
    for (const auto& [q, block] : row.right) {
      if (q >= p0 && in_b[q]) part.emplace_back(order_of[local[q - p0]], &block);
    }
    for (const auto& [a, block_a] : part) {
      gradient[a].noalias() -= block_a->transpose() * boundary_rhs[k].second;
      for (const auto& [b, block_b] : part) {
        if (a > b) continue;
        add_row_block(a, b, -(block_a->transpose() * *block_b));
      }
    }
  }
  std::vector<RBlockRow> rows;
  std::string error;
  if (!batch_.FactorNormalEquations(std::move(columns), std::move(gradient), &rows, &error)) {
    result->status = Status::Error(ErrorCode::kNumericalFailure, error);
    return false;
  }

  // 6. Commit (nothing fails from here): linearisation points, factor records, R, positions.
  const int first_b = p0 + static_cast<int>(kept.size());
  std::vector<int> new_position(n - p0);
  for (size_t k = 0; k < kept.size(); ++k) new_position[kept[k] - p0] = p0 + static_cast<int>(k);
  for (int k = 0; k < nb; ++k) new_position[b_positions[k] - p0] = first_b + order_of[k];
  for (RBlockRow& row : rows) {
    for (auto& entry : row.right) entry.first += first_b;
  }
  size_t next_relinearized = 0;
  for (const LocalFactor& lf : local_factors) {
    if (lf.relinearize) MarkInR(lf.id, relinearized_at[next_relinearized++]);
  }
  std::vector<Eigen::Vector3d> old_delta(delta_.begin() + p0, delta_.end());
  for (int p : drifted_positions) {
    Variable& v = vars_[position_to_var_[p]];
    v.linearization = Retract(v.linearization, delta_[p]);
    old_delta[p - p0] = Eigen::Vector3d::Zero();
    delta_[p].setZero();
  }
  MutableR().ReplaceTail(p0, new_position, kept, std::move(rows), boundary_rhs);
  std::vector<int> old_vars(position_to_var_.begin() + p0, position_to_var_.end());
  for (int k = 0; k < n - p0; ++k) {
    const int p = new_position[k];
    position_to_var_[p] = old_vars[k];
    vars_[old_vars[k]].position = p;
    delta_[p] = old_delta[k];
  }
  if (options_.backsubstitution_threshold == 0.0) {
    r_->BackSubstitute(&delta_);
    result->rows_backsubstituted += r_->size();
  } else {
    std::vector<int> dirty;
    for (int p = p0; p < n; ++p) dirty.push_back(p);
    for (int r : boundary) dirty.push_back(r < p0 ? r : new_position[r - p0]);
    result->rows_backsubstituted +=
        MutableR().BackSubstitutePartial(dirty, options_.backsubstitution_threshold, &delta_);
  }
  ++stats_.partial_relinearizations;
  stats_.relinearized_variables += static_cast<int64_t>(drifted_positions.size());
  stats_.rows_reeliminated += nb;
  stats_.partial_seconds += Seconds(start);
  result->relinearized = static_cast<int>(drifted_positions.size());
  return true;
}

bool Smoother::Impl::FactorAll(const std::vector<int64_t>& included, UpdateResult* result) {
  std::vector<LinearizedFactor> linearized(included.size());
  std::vector<PositionedFactor> positioned(included.size());
  std::array<Pose2, kMaxFactorKeys> values;
  for (size_t k = 0; k < included.size(); ++k) {
    const FactorRecord& f = factors_[included[k]];
    for (int j = 0; j < f.num_vars; ++j) values[j] = vars_[f.vars[j]].linearization;
    linearized[k] = Linearize(f.factor, values.data());
    MarkInR(included[k], values);
    positioned[k].num_keys = f.num_vars;
    for (int j = 0; j < f.num_vars; ++j) positioned[k].positions[j] = vars_[f.vars[j]].position;
    positioned[k].jacobians = linearized[k].jacobians.data();
    positioned[k].rhs = -linearized[k].whitened_error;
  }
  std::vector<RBlockRow> rows;
  std::string error;
  if (!batch_.Factor(static_cast<int>(position_to_var_.size()), positioned, &rows, &error)) {
    result->status = Status::Error(error);
    return false;
  }
  FreshR().Assign(std::move(rows));
  r_->BackSubstitute(&delta_);
  return true;
}

double Smoother::Impl::Chi2Of(const std::vector<int64_t>& included,
                              const std::vector<Eigen::Vector3d>& step) const {
  double chi2 = 0.0;
  std::array<Pose2, kMaxFactorKeys> values;
  for (int64_t id : included) {
    const FactorRecord& f = factors_[id];
    for (int j = 0; j < f.num_vars; ++j) {
      const Variable& v = vars_[f.vars[j]];
      values[j] = step.empty() ? v.linearization : Retract(v.linearization, step[v.position]);
    }
    chi2 += FactorChi2(f.factor, values.data());
  }
  return chi2;
}

void Smoother::Impl::BatchStep(bool converge, double tolerance, UpdateResult* result) {
  const auto start = std::chrono::steady_clock::now();
  const int iterations_before = result->iterations;
  tolerance_ = tolerance;
  Snapshot before = Save();
  auto fail = [&](Status status) {
    Restore(std::move(before));
    result->status = std::move(status);
    result->iterations = iterations_before;
    stats_.batch_seconds += Seconds(start);
    ++stats_.failed_batch_steps;
  };
  result->batch_step = true;
  // Relinearise everything at the current estimate.
  for (Variable& v : vars_) {
    if (v.position >= 0) v.linearization = Retract(v.linearization, delta_[v.position]);
  }
  // Start from scratch: every active factor is pending, grounding starts at the priors.
  for (FactorLinearization& lin : factor_lin_) lin.in_r = false;
  pending_factors_.clear();
  for (size_t f = 0; f < factors_.size(); ++f) {
    if (factors_[f].active) pending_factors_.push_back(static_cast<int64_t>(f));
  }
  std::vector<char> grounded(vars_.size(), 0);
  const std::vector<int64_t> included = GroundPendingFactors(&grounded);

  // Ordering over the grounded variables; anchors and each trajectory's latest pose last.
  std::vector<int> dense(vars_.size(), -1), dense_to_var;
  for (size_t v = 0; v < vars_.size(); ++v) {
    if (grounded[v]) {
      dense[v] = static_cast<int>(dense_to_var.size());
      dense_to_var.push_back(static_cast<int>(v));
    }
  }
  std::vector<std::vector<int>> factor_vars(included.size());
  for (size_t k = 0; k < included.size(); ++k) {
    const FactorRecord& f = factors_[included[k]];
    for (int j = 0; j < f.num_vars; ++j) factor_vars[k].push_back(dense[f.vars[j]]);
  }
  std::unordered_map<TrajectoryId, std::pair<int32_t, int>> latest;  // trajectory -> (index, dense)
  std::vector<bool> keep_last(dense_to_var.size(), false);
  for (size_t d = 0; d < dense_to_var.size(); ++d) {
    const Key& key = vars_[dense_to_var[d]].key;
    if (key.is_anchor()) {
      keep_last[d] = true;
      continue;
    }
    auto [it, inserted] = latest.try_emplace(key.trajectory, key.index, static_cast<int>(d));
    if (!inserted && key.index > it->second.first) it->second = {key.index, static_cast<int>(d)};
  }
  for (const auto& [t, entry] : latest) keep_last[entry.second] = true;
  Result<std::vector<int>> ordering =
      ComputeOrdering(static_cast<int>(dense_to_var.size()), factor_vars, keep_last);
  if (!ordering.ok()) return fail(ordering.status());
  const std::vector<int>& order = *ordering;
  for (Variable& v : vars_) v.position = -1;
  grounded_.clear();
  position_to_var_.clear();
  for (int d : order) {
    vars_[dense_to_var[d]].position = static_cast<int>(position_to_var_.size());
    position_to_var_.push_back(dense_to_var[d]);
  }
  delta_.assign(position_to_var_.size(), Eigen::Vector3d::Zero());
  TakeOutOfPending(included);

  const int max_iterations = converge ? options_.max_batch_iterations : 1;
  if (options_.method == NonlinearMethod::kDogLeg) {
    DogLegIterations(included, max_iterations, result);
  } else {
    GaussNewtonIterations(included, max_iterations, result);
  }
  if (!result->status.ok()) return fail(result->status);
  nonzeros_after_batch_ = r_->NonZeros();
  updates_since_batch_ = 0;
  stats_.batch_seconds += Seconds(start);
  ++stats_.batch_steps;
  stats_.batch_iterations += result->iterations - iterations_before;
}

void Smoother::Impl::GaussNewtonIterations(const std::vector<int64_t>& included, int max_iterations,
                                           UpdateResult* result) {
  // R stays linearised at the last point; the final delta is kept (not folded into the
  // linearisation point) so that incremental updates continue consistently from R.
  for (int it = 0; it < max_iterations; ++it) {
    if (it > 0) {
      for (int var : position_to_var_) {
        Variable& v = vars_[var];
        v.linearization = Retract(v.linearization, delta_[v.position]);
      }
    }
    if (!FactorAll(included, result)) return;
    ++result->iterations;
    if (MaxAbs(delta_) < tolerance_) break;
  }
  stats_.iterations_to_convergence += result->iterations;
}

void Smoother::Impl::DogLegIterations(const std::vector<int64_t>& included, int max_iterations,
                                      UpdateResult* result) {
  // Powell's dog-leg: blend the Gauss-Newton step with steepest descent inside a trust
  // region, accept a step only if chi2 decreases.
  double radius = options_.dogleg_initial_radius;
  double chi2 = Chi2Of(included, {});
  const int n = static_cast<int>(position_to_var_.size());
  for (int it = 0; it < max_iterations; ++it) {
    if (!FactorAll(included, result)) return;
    ++result->iterations;
    const std::vector<Eigen::Vector3d> gauss_newton = delta_;
    // Gradient direction g = J^T b (b = -whitened error) and |J g|^2.
    std::vector<Eigen::Vector3d> g(n, Eigen::Vector3d::Zero());
    std::vector<LinearizedFactor> lin(included.size());
    std::array<Pose2, kMaxFactorKeys> values;
    for (size_t k = 0; k < included.size(); ++k) {
      const FactorRecord& f = factors_[included[k]];
      for (int j = 0; j < f.num_vars; ++j) values[j] = vars_[f.vars[j]].linearization;
      lin[k] = Linearize(f.factor, values.data());
      for (int j = 0; j < f.num_vars; ++j) {
        g[vars_[f.vars[j]].position] -= lin[k].jacobians[j].transpose() * lin[k].whitened_error;
      }
    }
    auto apply_J = [&](const std::vector<Eigen::Vector3d>& h) {
      double norm2 = 0.0;
      for (size_t k = 0; k < included.size(); ++k) {
        const FactorRecord& f = factors_[included[k]];
        Eigen::Vector3d r = Eigen::Vector3d::Zero();
        for (int j = 0; j < f.num_vars; ++j)
          r += lin[k].jacobians[j] * h[vars_[f.vars[j]].position];
        norm2 += r.squaredNorm();
      }
      return norm2;
    };
    auto norm = [](const std::vector<Eigen::Vector3d>& v) {
      double s = 0.0;
      for (const auto& x : v) s += x.squaredNorm();
      return std::sqrt(s);
    };
    auto dot = [](const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b) {
      double s = 0.0;
      for (size_t i = 0; i < a.size(); ++i) s += a[i].dot(b[i]);
      return s;
    };
    const double g_norm = norm(g);
    const double Jg2 = apply_J(g);
    const double alpha = Jg2 > 0 ? g_norm * g_norm / Jg2 : 0.0;
    const double gn_norm = norm(gauss_newton);

    bool accepted = false;
    std::vector<Eigen::Vector3d> h(n);
    while (!accepted && radius > 1e-12) {
      if (gn_norm <= radius) {
        h = gauss_newton;
      } else if (alpha * g_norm >= radius) {
        for (int p = 0; p < n; ++p) h[p] = (radius / g_norm) * g[p];
      } else {
        // h = a + beta (b - a) with |h| = radius, a = alpha g, b = Gauss-Newton.
        std::vector<Eigen::Vector3d> a(n), ba(n);
        for (int p = 0; p < n; ++p) {
          a[p] = alpha * g[p];
          ba[p] = gauss_newton[p] - a[p];
        }
        const double aa = dot(a, a), ab = dot(a, ba), bb = dot(ba, ba);
        const double beta = (-ab + std::sqrt(ab * ab + bb * (radius * radius - aa))) / bb;
        for (int p = 0; p < n; ++p) h[p] = a[p] + beta * ba[p];
      }
      const double predicted = 2.0 * dot(g, h) - apply_J(h);
      const double new_chi2 = Chi2Of(included, h);
      const double rho = predicted > 0 ? (chi2 - new_chi2) / predicted : -1.0;
      if (rho > 0.75) {
        radius = std::max(radius, 3.0 * norm(h));
      } else if (rho < 0.25) {
        radius *= 0.5;
      }
      if (rho > 0 || (chi2 - new_chi2) >= 0.0) {
        accepted = true;
        for (int var : position_to_var_) {
          Variable& v = vars_[var];
          v.linearization = Retract(v.linearization, h[v.position]);
        }
        chi2 = new_chi2;
      }
    }
    if (!accepted || MaxAbs(h) < tolerance_) break;
  }
  stats_.iterations_to_convergence += result->iterations;
  // Leave R linearised at the final point, with its Gauss-Newton solution as delta.
  FactorAll(included, result);
}

UpdateResult Smoother::Impl::Update(bool force_batch, double convergence_step) {
  const auto start = std::chrono::steady_clock::now();
  UpdateResult result;
  result.update = ++stats_.updates;
  covariances_.reset();
  const int anchors_before = CountAnchors();
  const int waiting_before = ActivePending();

  ++updates_since_batch_;
  const bool on_clock =
      options_.batch_every_updates > 0 && updates_since_batch_ >= options_.batch_every_updates;
  const bool on_fill = options_.batch_when_fill_grows > 0 && nonzeros_after_batch_ > 0 &&
                       r_->NonZeros() > options_.batch_when_fill_grows * nonzeros_after_batch_;
  if (force_batch || merge_pending_ || on_clock || on_fill) {
    if (merge_pending_) {
      ++stats_.batch_steps_on_merge;
      result.groups_merged = 1;
    } else if (on_clock) {
      ++stats_.batch_steps_on_clock;
    } else if (on_fill) {
      ++stats_.batch_steps_on_fill;
    }
    const bool converge = force_batch || merge_pending_ || options_.converge_periodic_batches;
    BatchStep(converge, convergence_step > 0 ? convergence_step : options_.convergence_step,
              &result);
    if (result.status.ok()) merge_pending_ = false;  // else the next update tries again
  } else {
    IncrementalStep(&result);
    stats_.incremental_seconds += Seconds(start);
    if (options_.relinearize_threshold > 0 && result.status.ok() &&
        ++updates_since_drift_check_ >= options_.relinearize_skip &&
        MaxDrift() > options_.relinearize_threshold) {
      updates_since_drift_check_ = 0;
      if (options_.partial_relinearization) {
        PartialRelinearization(&result);
      } else {
        ++stats_.batch_steps_on_drift;
        BatchStep(options_.converge_periodic_batches, options_.convergence_step, &result);
      }
    }
  }
  if (!pending_vars_.empty() && result.status.ok()) {
    result.status = Status::Error(std::to_string(pending_vars_.size()) +
                                  " variable(s) wait for measurements that determine them, e.g. " +
                                  vars_[pending_vars_.front()].key.ToString());
  }
  // Factors that waited and are in R now (a batch step refactors the others too).
  result.factors_added = waiting_before - ActivePending();
  result.anchors_created = CountAnchors() - anchors_before;
  stats_.rows_backsubstituted += result.rows_backsubstituted;
  stats_.nnz_r = r_->NonZeros();
  stats_.givens_block_rows = r_->eliminated_block_rows();
  stats_.givens_block_columns = r_->eliminated_block_columns();
  result.seconds = Seconds(start);
  return result;
}

int Smoother::Impl::CountAnchors() const {
  int anchors = 0;
  for (int var : position_to_var_) anchors += vars_[var].key.is_anchor() ? 1 : 0;
  return anchors;
}

double Smoother::Impl::MaxAbs(const std::vector<Eigen::Vector3d>& v) {
  double m = 0.0;
  for (const auto& x : v) m = std::max(m, x.cwiseAbs().maxCoeff());
  return m;
}

// --- Queries ---------------------------------------------------------------------------

Eigen::MatrixXd Smoother::Impl::JointCovariance(const std::vector<Key>& keys) {
  if (!covariances_) covariances_ = std::make_unique<CovarianceRecovery>(r_);
  std::vector<int> positions;
  for (const Key& key : keys) {
    auto it = index_.find(key);
    if (it == index_.end() || vars_[it->second].position < 0) {
      throw std::invalid_argument("no covariance for " + key.ToString() +
                                  ": not a solved variable (see HasCovariance)");
    }
    positions.push_back(vars_[it->second].position);
  }
  return covariances_->Joint(positions);
}

double Smoother::Impl::Chi2() const {
  double chi2 = 0.0;
  std::array<Pose2, kMaxFactorKeys> values;
  for (const FactorRecord& f : factors_) {
    if (!f.active) continue;
    for (int j = 0; j < f.num_vars; ++j) values[j] = EstimateOf(f.vars[j]);
    chi2 += FactorChi2(f.factor, values.data());
  }
  return chi2;
}

// --- Smoother --------------------------------------------------------------------------

Smoother::Smoother(const SmootherOptions& options) : impl_(std::make_unique<Impl>(options)) {}
Smoother::~Smoother() = default;
Smoother::Smoother(Smoother&&) noexcept = default;
Smoother& Smoother::operator=(Smoother&&) noexcept = default;

const SmootherOptions& Smoother::options() const { return impl_->options(); }
Status Smoother::AddPose(PoseKey key, const Pose2& initial) { return impl_->AddPose(key, initial); }
Status Smoother::AddBetween(PoseKey from, PoseKey to, const Pose2& z, const Eigen::Matrix3d& cov) {
  return impl_->AddBetween(from, to, z, cov);
}
Status Smoother::AddEncounter(PoseKey a, PoseKey b, const Pose2& z, const Eigen::Matrix3d& cov) {
  return impl_->AddEncounter(a, b, z, cov);
}
UpdateResult Smoother::Update() { return impl_->Update(false, 0.0); }
UpdateResult Smoother::BatchOptimize(double convergence_step) {
  return impl_->Update(true, convergence_step);
}
bool Smoother::HasPose(PoseKey key) const { return impl_->Has(key); }
int Smoother::NumPoses(TrajectoryId t) const { return impl_->NumPoses(t); }
std::vector<TrajectoryId> Smoother::Trajectories() const { return impl_->trajectory_order(); }
Pose2 Smoother::FramePose(PoseKey key) const { return impl_->Estimate(key); }
Pose2 Smoother::GlobalPose(PoseKey key) const { return impl_->GlobalPose(key); }
bool Smoother::IsAnchored(TrajectoryId t) const { return impl_->IsAnchored(t); }
std::optional<Pose2> Smoother::Anchor(TrajectoryId t) const {
  if (!impl_->IsAnchored(t)) return std::nullopt;
  return impl_->Estimate(AnchorKey{t});
}
TrajectoryId Smoother::GroupRoot(TrajectoryId t) const { return impl_->GroupRoot(t); }
Eigen::Matrix3d Smoother::MarginalCovariance(const Key& key) {
  return impl_->JointCovariance({key});
}
Eigen::MatrixXd Smoother::JointCovariance(const std::vector<Key>& keys) {
  return impl_->JointCovariance(keys);
}
double Smoother::Chi2() const { return impl_->Chi2(); }
Pose2 Smoother::Value(const Key& key) const { return impl_->Estimate(key); }
bool Smoother::HasVariable(const Key& key) const { return impl_->Has(key); }
bool Smoother::HasCovariance(const Key& key) const { return impl_->HasCovariance(key); }
std::vector<Factor> Smoother::ActiveFactors() const { return impl_->ActiveFactors(); }
Smoother::LinearSystem Smoother::LinearSystemForTesting() const {
  return impl_->LinearSystemForTesting();
}
const SmootherStats& Smoother::stats() const { return impl_->stats(); }
std::vector<Pose2> Smoother::GlobalTrajectory(TrajectoryId t) const {
  std::vector<Pose2> poses;
  for (int32_t i = 0; impl_->Has(PoseKey{t, i}); ++i) poses.push_back(impl_->GlobalPose({t, i}));
  return poses;
}

}  // namespace anchormap
