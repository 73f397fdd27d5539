// The Smoother's facade over pose aliases (a keyframe folded onto a node: AddAlias): a
// measurement on an alias lands on its node, and a query on an alias resolves through its
// node's estimate and Jacobians, so that callers ask for keyframes' poses and covariances by
// their keys whether folded or not. The variables' own work is in smoother_impl.h.

#include <algorithm>
#include <string>
#include <utility>
#include <vector>

#include "common/geometry/covariance.h"
#include "common/solver/smoother.h"
#include "common/solver/smoother_impl.h"

namespace anchormap {

Status Smoother::AddAlias(PoseKey key, PoseKey node, const Pose2& T_node_key,
                          const Eigen::Matrix3d& covariance) {
  if (HasPose(key)) return Status::Error("pose " + Key(key).ToString() + " exists already");
  if (key.index < 1 || impl_->NumPoses(key.trajectory) == 0) {
    return Status::Error("an alias needs its trajectory's first pose to be a variable");
  }
  if (!impl_->Has(node)) return Status::Error("alias of " + Key(node).ToString() + ": no variable");
  if (node.trajectory != key.trajectory && impl_->options().formulation == Formulation::kRelative &&
      !(impl_->IsAnchored(node.trajectory) && impl_->IsAnchored(key.trajectory) &&
        impl_->GroupRoot(node.trajectory) == impl_->GroupRoot(key.trajectory))) {
    return Status::Error("alias across trajectories that are not anchored in one group");
  }
  if (!T_node_key.IsFinite()) return Status::Error("alias offset is not finite");
  if (!covariance.isZero(0.0)) {  // zero: a borrowed node's keyframe
    if (Status problem = CheckSymmetricPositiveDefinite(covariance); !problem.ok()) {
      return Status::Error("alias covariance rejected: " + problem.message());
    }
  }
  aliases_.Add(key, {node, T_node_key, covariance});
  return Status::Ok();
}

Status Smoother::AddBetween(PoseKey from, PoseKey to, const Pose2& z, const Eigen::Matrix3d& cov) {
  const PoseAlias* alias_from = aliases_.Find(from);
  const PoseAlias* alias_to = aliases_.Find(to);
  if (alias_from == nullptr && alias_to == nullptr) return impl_->AddBetween(from, to, z, cov);
  if (!HasPose(from) || !HasPose(to)) return Status::Error("between factor on an unknown pose");
  if (from.trajectory != to.trajectory) {
    return Status::Error("between factor joins two trajectories: use AddEncounter");
  }
  if (from == to) return Status::Error("between factor from a pose to itself");
  return AddBetweenNodes(MapToNodes(from, alias_from, to, alias_to, z, cov));
}

Status Smoother::AddEncounter(PoseKey a, PoseKey b, const Pose2& z, const Eigen::Matrix3d& cov) {
  const PoseAlias* alias_a = aliases_.Find(a);
  const PoseAlias* alias_b = aliases_.Find(b);
  if (alias_a == nullptr && alias_b == nullptr) return impl_->AddEncounter(a, b, z, cov);
  if (!HasPose(a) || !HasPose(b)) return Status::Error("encounter on an unknown pose");
  if (a.trajectory == b.trajectory) {
    return Status::Error("encounter within one trajectory: use AddBetween (a loop closure)");
  }
  return AddBetweenNodes(MapToNodes(a, alias_a, b, alias_b, z, cov));
}

Status Smoother::AddBetweenNodes(const NodeMeasurement& m) {
  if (m.inside_one_node()) {
    ++measurements_inside_nodes_;
    return Status::Ok();
  }
  return m.a.trajectory == m.b.trajectory
             ? impl_->AddBetween(m.a, m.b, m.measured_T_a_b, m.covariance)
             : impl_->AddEncounter(m.a, m.b, m.measured_T_a_b, m.covariance);
}

Pose2 Smoother::FramePose(PoseKey key) const {
  const PoseAlias* alias = aliases_.Find(key);
  if (alias == nullptr) return impl_->Estimate(key);
  if (alias->node.trajectory == key.trajectory ||
      impl_->options().formulation != Formulation::kRelative) {
    return Compose(impl_->Estimate(alias->node), alias->T_node_key);
  }
  return Between(impl_->Estimate(AnchorKey{key.trajectory}),
                 Compose(impl_->GlobalPose(alias->node), alias->T_node_key));
}

Pose2 Smoother::GlobalPose(PoseKey key) const {
  const PoseAlias* alias = aliases_.Find(key);
  if (alias == nullptr) return impl_->GlobalPose(key);
  return Compose(impl_->GlobalPose(alias->node), alias->T_node_key);
}

std::vector<std::pair<Key, Eigen::Matrix3d>> Smoother::Terms(const Key& key) const {
  const PoseAlias* alias = key.is_anchor() ? nullptr : aliases_.Find(key.pose());
  if (alias == nullptr) return {{key, Eigen::Matrix3d::Identity()}};
  Eigen::Matrix3d J_node, J_offset;
  if (alias->node.trajectory == key.trajectory ||
      impl_->options().formulation != Formulation::kRelative) {
    Compose(impl_->Estimate(alias->node), alias->T_node_key, &J_node, &J_offset);
    return {{Key(alias->node), J_node}};
  }
  // FramePose = Between(A_key, A_node (+) x_node (+) offset).
  const AnchorKey anchor_node{alias->node.trajectory}, anchor_key{key.trajectory};
  Eigen::Matrix3d J_inner, J_anchor_node, J_global, J_anchor_key, J_between;
  const Pose2 inner = Compose(impl_->Estimate(alias->node), alias->T_node_key, &J_node, &J_offset);
  const Pose2 global = Compose(impl_->Estimate(anchor_node), inner, &J_anchor_node, &J_inner);
  Between(impl_->Estimate(anchor_key), global, &J_anchor_key, &J_between);
  return {{Key(alias->node), J_between * J_inner * J_node},
          {Key(anchor_node), J_between * J_anchor_node},
          {Key(anchor_key), J_anchor_key}};
}

bool Smoother::AnyAlias(const std::vector<Key>& keys) const {
  if (aliases_.empty()) return false;
  return std::any_of(keys.begin(), keys.end(), [this](const Key& key) {
    return !key.is_anchor() && aliases_.Find(key.pose()) != nullptr;
  });
}

Smoother::CovarianceQuery Smoother::OnVariables(
    const std::vector<Key>& keys, const std::vector<Eigen::Matrix3d>& jacobians) const {
  CovarianceQuery out;
  for (size_t i = 0; i < keys.size(); ++i) {
    for (const auto& [variable, J] : Terms(keys[i])) {
      const auto it = std::find(out.keys.begin(), out.keys.end(), variable);
      if (it == out.keys.end()) {
        out.keys.push_back(variable);
        out.jacobians.push_back(jacobians[i] * J);
      } else {
        out.jacobians[static_cast<size_t>(it - out.keys.begin())] += jacobians[i] * J;
      }
    }
  }
  return out;
}

Eigen::MatrixXd Smoother::JointCovariance(const std::vector<Key>& keys) {
  if (!AnyAlias(keys)) return impl_->JointCovariance(keys);
  // Sigma_keys = E Sigma_variables E^T, E the keys' Jacobians on their variables.
  std::vector<Key> variables;
  std::vector<std::vector<std::pair<Key, Eigen::Matrix3d>>> terms;
  for (const Key& key : keys) {
    terms.push_back(Terms(key));
    for (const auto& term : terms.back()) {
      if (std::find(variables.begin(), variables.end(), term.first) == variables.end()) {
        variables.push_back(term.first);
      }
    }
  }
  Eigen::MatrixXd E = Eigen::MatrixXd::Zero(3 * static_cast<Eigen::Index>(keys.size()),
                                            3 * static_cast<Eigen::Index>(variables.size()));
  for (size_t i = 0; i < keys.size(); ++i) {
    for (const auto& [variable, J] : terms[i]) {
      const auto j = std::find(variables.begin(), variables.end(), variable) - variables.begin();
      E.block<3, 3>(3 * static_cast<Eigen::Index>(i), 3 * j) += J;
    }
  }
  return E * impl_->JointCovariance(variables) * E.transpose();
}

Eigen::Matrix3d Smoother::ProjectedCovariance(const std::vector<Key>& keys,
                                              const std::vector<Eigen::Matrix3d>& jacobians) {
  if (!AnyAlias(keys)) return impl_->ProjectedCovariance(keys, jacobians);
  const CovarianceQuery query = OnVariables(keys, jacobians);
  return impl_->ProjectedCovariance(query.keys, query.jacobians);
}

bool Smoother::ProjectedCovarianceUntil(const std::vector<Key>& keys,
                                        const std::vector<Eigen::Matrix3d>& jacobians,
                                        const std::function<bool(const Eigen::Matrix3d&)>& enough,
                                        Eigen::Matrix3d* covariance) {
  if (!AnyAlias(keys)) return impl_->ProjectedCovarianceUntil(keys, jacobians, enough, covariance);
  const CovarianceQuery query = OnVariables(keys, jacobians);
  return impl_->ProjectedCovarianceUntil(query.keys, query.jacobians, enough, covariance);
}

std::vector<Eigen::Matrix3d> Smoother::ProjectedMarginals(const std::vector<Key>& keys) {
  if (!AnyAlias(keys)) return impl_->ProjectedMarginals(keys);
  std::vector<CovarianceQuery> queries;
  for (const Key& key : keys) queries.push_back(OnVariables({key}, {Eigen::Matrix3d::Identity()}));
  return impl_->ProjectedCovariances(queries);
}

std::vector<Eigen::Matrix3d> Smoother::ProjectedCovariances(
    const std::vector<CovarianceQuery>& queries) {
  if (aliases_.empty()) return impl_->ProjectedCovariances(queries);
  std::vector<CovarianceQuery> on_variables;
  on_variables.reserve(queries.size());
  for (const CovarianceQuery& query : queries) {
    on_variables.push_back(AnyAlias(query.keys) ? OnVariables(query.keys, query.jacobians) : query);
  }
  return impl_->ProjectedCovariances(on_variables);
}

Pose2 Smoother::Value(const Key& key) const {
  if (!key.is_anchor() && aliases_.Find(key.pose()) != nullptr) return FramePose(key.pose());
  return impl_->Estimate(key);
}

bool Smoother::HasCovariance(const Key& key) const {
  if (key.is_anchor() || aliases_.Find(key.pose()) == nullptr) return impl_->HasCovariance(key);
  const auto terms = Terms(key);
  return std::all_of(terms.begin(), terms.end(),
                     [this](const auto& term) { return impl_->HasCovariance(term.first); });
}

}  // namespace anchormap
