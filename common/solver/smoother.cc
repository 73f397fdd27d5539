#include "common/solver/smoother.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>

#include <Eigen/Dense>

#include "common/solver/smoother_impl.h"

#include "common/geometry/covariance.h"

namespace anchormap {

int Smoother::Impl::AddVariable(const Key& key, const Pose2& initial) {
  const int var = static_cast<int>(vars_.size());
  vars_.push_back({key, initial, -1});
  correction_.push_back(Eigen::Vector3d::Zero());
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
  counted_in_gradient_.push_back(0);
  pending_factors_.push_back(static_cast<int64_t>(factors_.size()) - 1);
  ++stats_.factors;
  return static_cast<int64_t>(factors_.size()) - 1;
}

void Smoother::Impl::SetValue(int var, const Pose2& value) {
  // Only used right before a batch step, which relinearises everything.
  vars_[var].linearization = value;
  if (vars_[var].position >= 0) delta_[vars_[var].position].setZero();
  correction_[var].setZero();
}

Status Smoother::Impl::CheckMeasurement(const Pose2& z, const Eigen::Matrix3d& covariance) const {
  if (!z.IsFinite()) return Status::Error("measurement is not finite");
  if (Status problem = CheckSymmetricPositiveDefinite(covariance); !problem.ok()) {
    return Status::Error("covariance rejected: " + problem.message());
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
      return Status::Error("trajectory " + std::to_string(key.trajectory.value()) +
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
      const Pose2 moved = Compose(T_new_old, EstimateOf(var));
      const int position = vars_[var].position;
      if (MergesByPartialStep() && position >= 0) {
        // R stays as it is; the partial merge step relinearises this anchor at `moved`.
        const Pose2& theta = vars_[var].linearization;
        delta_[position] =
            Eigen::Vector3d(moved.x() - theta.x(), moved.y() - theta.y(),
                            std::remainder(moved.theta() - theta.theta(), 2.0 * M_PI));
        correction_[var].setZero();
        merge_vars_.push_back(var);
      } else {
        SetValue(var, moved);
      }
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
    counted_in_gradient_[merge.absorbed_prior_id] = 0;
    merge_pending_ = true;
    if (MergesByPartialStep()) merge_vars_.push_back(factors_[merge.absorbed_prior_id].vars[0]);
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

int Smoother::Impl::CountAnchors() const {
  // By trajectory, not by variable: this runs twice per update, and a trajectory has at
  // most one anchor.
  int anchors = 0;
  for (TrajectoryId t : trajectory_order_) {
    auto it = index_.find(AnchorKey{t});
    anchors += it != index_.end() && vars_[it->second].position >= 0 ? 1 : 0;
  }
  return anchors;
}

double Smoother::Impl::MaxAbs(const std::vector<Eigen::Vector3d>& v) {
  double m = 0.0;
  for (const auto& x : v) m = std::max(m, x.cwiseAbs().maxCoeff());
  return m;
}

// --- Queries ---------------------------------------------------------------------------

std::vector<int> Smoother::Impl::SolvedPositions(const std::vector<Key>& keys) const {
  std::vector<int> positions;
  for (const Key& key : keys) {
    auto it = index_.find(key);
    if (it == index_.end() || vars_[it->second].position < 0) {
      throw std::invalid_argument("no covariance for " + key.ToString() +
                                  ": not a solved variable (see HasCovariance)");
    }
    positions.push_back(vars_[it->second].position);
  }
  return positions;
}

Eigen::MatrixXd Smoother::Impl::JointCovariance(const std::vector<Key>& keys) {
  const std::vector<int> positions = SolvedPositions(keys);
  if (!covariances_) covariances_ = std::make_unique<CovarianceRecovery>(r_);
  return covariances_->Joint(positions);
}

Eigen::Matrix3d Smoother::Impl::ProjectedCovariance(const std::vector<Key>& keys,
                                                    const std::vector<Eigen::Matrix3d>& jacobians) {
  return projected_.Compute(*r_, SolvedPositions(keys), jacobians);
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
Status Smoother::AddPose(PoseKey key, const Pose2& initial) {
  if (aliases_.Find(key) != nullptr) {
    return Status::Error("pose " + Key(key).ToString() + " exists already (an alias)");
  }
  Status status = impl_->AddPose(key, initial);
  if (status.ok() && key.index >= kBorrowedNodeIndexBase) ++borrowed_nodes_[key.trajectory];
  return status;
}

PoseKey Smoother::NextBorrowedNode(TrajectoryId t) const {
  const auto it = borrowed_nodes_.find(t);
  return {t, kBorrowedNodeIndexBase + (it == borrowed_nodes_.end() ? 0 : it->second)};
}

UpdateResult Smoother::Update() { return impl_->Update(false, 0.0); }
UpdateResult Smoother::BatchOptimize(double convergence_step) {
  return impl_->Update(true, convergence_step);
}
bool Smoother::HasPose(PoseKey key) const {
  return impl_->Has(key) || aliases_.Find(key) != nullptr;
}
int Smoother::NumPoses(TrajectoryId t) const {
  if (borrowed_nodes_.empty() && aliases_.empty()) return impl_->NumPoses(t);
  const auto borrowed = borrowed_nodes_.find(t);
  return impl_->NumPoses(t) + aliases_.Count(t) -
         (borrowed == borrowed_nodes_.end() ? 0 : borrowed->second);
}
std::vector<TrajectoryId> Smoother::Trajectories() const { return impl_->trajectory_order(); }

bool Smoother::IsAnchored(TrajectoryId t) const { return impl_->IsAnchored(t); }
std::optional<Pose2> Smoother::Anchor(TrajectoryId t) const {
  if (!impl_->IsAnchored(t)) return std::nullopt;
  return impl_->Estimate(AnchorKey{t});
}
TrajectoryId Smoother::GroupRoot(TrajectoryId t) const { return impl_->GroupRoot(t); }
Eigen::Matrix3d Smoother::MarginalCovariance(const Key& key) { return JointCovariance({key}); }
double Smoother::Chi2() const { return impl_->Chi2(); }
bool Smoother::HasVariable(const Key& key) const { return impl_->Has(key); }
bool Smoother::IsSolved(const Key& key) const {
  return HasCovariance(key) && !impl_->GroupChangePending();
}
bool Smoother::GroupChangePending() const { return impl_->GroupChangePending(); }
bool Smoother::HasPendingChanges() const { return impl_->HasPendingChanges(); }
std::vector<Factor> Smoother::ActiveFactors() const { return impl_->ActiveFactors(); }
Smoother::LinearSystem Smoother::LinearSystemForTesting() const {
  return impl_->LinearSystemForTesting();
}
SmootherState Smoother::ExportState() const {
  SmootherState state = impl_->ExportState();
  state.aliases = NumAliases();
  state.measurements_inside_nodes = measurements_inside_nodes_;
  return state;
}

Status Smoother::ImportState(SmootherState state) {
  if (state.aliases != NumAliases() ||
      state.measurements_inside_nodes != measurements_inside_nodes_) {
    return Status::Error(ErrorCode::kInvalidArgument,
                         "smoother state refused: other aliases (" + std::to_string(state.aliases) +
                             " aliases, " + std::to_string(state.measurements_inside_nodes) +
                             " measurements inside nodes; this graph " +
                             std::to_string(NumAliases()) + ", " +
                             std::to_string(measurements_inside_nodes_) + ")");
  }
  return impl_->ImportState(std::move(state));
}
const SmootherStats& Smoother::stats() const { return impl_->stats(); }
CorrectionWork Smoother::correction_work() const { return impl_->correction_work(); }
std::vector<Pose2> Smoother::GlobalTrajectory(TrajectoryId t) const {
  if (aliases_.Count(t) > 0) {
    std::vector<Pose2> poses;
    poses.reserve(static_cast<size_t>(NumPoses(t)));
    for (int32_t i = 0; HasPose(PoseKey{t, i}); ++i) poses.push_back(GlobalPose(PoseKey{t, i}));
    return poses;
  }
  // GlobalPose per keyframe, with the anchor's estimate looked up once (the map publication
  // asks every keyframe of every trajectory twice per second of data): the same bits.
  const bool anchored =
      impl_->options().formulation == Formulation::kRelative && impl_->IsAnchored(t);
  const Pose2 anchor = anchored ? impl_->Estimate(AnchorKey{t}) : Pose2();
  const CosSin rotation = CosSin::Of(anchor.theta());  // once, not per keyframe: the same bits
  std::vector<Pose2> poses;
  poses.reserve(static_cast<size_t>(impl_->NumPoses(t)));
  for (int32_t i = 0; impl_->Has(PoseKey{t, i}); ++i) {
    const Pose2 local = impl_->Estimate(PoseKey{t, i});
    poses.push_back(anchored ? Compose(anchor, rotation, local) : local);
  }
  return poses;
}

}  // namespace anchormap
