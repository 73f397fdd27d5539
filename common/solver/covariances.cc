#include "common/solver/covariances.h"

#include <stdexcept>
#include <utility>

#include <Eigen/Dense>

namespace anchormap {

void CovarianceBlockMemo::Insert(uint64_t id, const Eigen::Matrix3d& value) {
  if (2 * (size_ + 1) > keys_.size()) Grow();
  size_t slot = Slot(id);
  while (keys_[slot] != kEmpty) slot = (slot + 1) & mask_;
  keys_[slot] = id;
  values_[slot] = value;
  ++size_;
}

void CovarianceBlockMemo::Grow() {
  std::vector<uint64_t> old_keys = std::move(keys_);
  std::vector<Eigen::Matrix3d> old_values = std::move(values_);
  const size_t capacity = old_keys.empty() ? 1024 : 2 * old_keys.size();
  keys_.assign(capacity, kEmpty);
  values_.resize(capacity);
  mask_ = capacity - 1;
  shift_ = 64;
  for (size_t c = capacity; c > 1; c >>= 1) --shift_;
  size_ = 0;
  for (size_t k = 0; k < old_keys.size(); ++k) {
    if (old_keys[k] != kEmpty) Insert(old_keys[k], old_values[k]);
  }
}

Eigen::Matrix3d CovarianceRecovery::Block(int i, int l) {
  if (i <= l) return Canonical(i, l);
  return Canonical(l, i).transpose();
}

const Eigen::Matrix3d& CovarianceRecovery::Canonical(int i0, int l0) {
  if (const Eigen::Matrix3d* known = Find(i0, l0)) return *known;
  // Explicit stack instead of recursion: chains of dependencies can be as long as the
  // trajectory. Dependencies of (i, l) have a larger first index, or the same first
  // index and a larger second one, so this terminates.
  std::vector<std::pair<int, int>>& stack = stack_;
  stack.assign(1, {i0, l0});
  while (!stack.empty()) {
    const auto [i, l] = stack.back();
    if (Find(i, l)) {
      stack.pop_back();
      continue;
    }
    const RBlockRow& row = r_->row(i);
    bool ready = true;
    inputs_.clear();
    for (const auto& [j, block] : row.right) {
      const int a = std::min(j, l), b = std::max(j, l);
      const Eigen::Matrix3d* input = Find(a, b);
      if (!input) {
        stack.emplace_back(a, b);
        ready = false;
      }
      inputs_.push_back(input);
    }
    if (!ready) continue;

    // sum_j R_ij Sigma_jl, with Sigma_jl = Sigma_lj^T when j > l.
    Eigen::Matrix3d sum = Eigen::Matrix3d::Zero();
    size_t k = 0;
    for (const auto& [j, block] : row.right) {
      if (j <= l) {
        sum.noalias() += block * *inputs_[k];
      } else {
        sum.noalias() += block * inputs_[k]->transpose();
      }
      ++k;
    }
    const auto Rii = row.diagonal.triangularView<Eigen::Upper>();
    Eigen::Matrix3d value;
    if (i == l) {
      const Eigen::Matrix3d Rinv_T = Rii.solve(Eigen::Matrix3d::Identity()).transpose();  // R_ll^-T
      value = Rii.solve(Rinv_T - sum);
      value = 0.5 * (value + value.transpose());  // symmetric by construction; remove round-off
    } else {
      value = -Rii.solve(sum);
    }
    memo_.Insert(Id(i, l), value);
    stack.pop_back();
  }
  return *Find(i0, l0);
}

Eigen::MatrixXd CovarianceRecovery::Joint(const std::vector<int>& positions) {
  const int k = static_cast<int>(positions.size());
  Eigen::MatrixXd joint(3 * k, 3 * k);
  for (int a = 0; a < k; ++a) {
    for (int b = a; b < k; ++b) {
      const Eigen::Matrix3d block = Block(positions[a], positions[b]);
      joint.block<3, 3>(3 * a, 3 * b) = block;
      joint.block<3, 3>(3 * b, 3 * a) = block.transpose();
    }
  }
  return joint;
}

Eigen::Matrix3d CovarianceProjection::Compute(const SparseR& r, const std::vector<int>& positions,
                                              const std::vector<Eigen::Matrix3d>& jacobians) {
  if (positions.size() != jacobians.size()) {
    throw std::invalid_argument("CovarianceProjection: one Jacobian block per position");
  }
  const int n = r.size();
  if (static_cast<int>(pending_.size()) < n) {
    pending_.resize(n, Eigen::Matrix3d::Zero());
    queued_.resize(n, 0);
  }
  for (int p : positions) {
    if (p < 0 || p >= n) throw std::out_of_range("CovarianceProjection: position outside R");
  }
  for (size_t s = 0; s < positions.size(); ++s) {
    const int p = positions[s];
    pending_[p] += jacobians[s].transpose();
    if (!queued_[p]) {
      queued_[p] = 1;
      queue_.push(p);
    }
  }
  // Forward substitution on R^T, rows in ascending order; each solved row pushes its part
  // into the rows its blocks reach (all later), so only ancestors are visited.
  Eigen::Matrix3d result = Eigen::Matrix3d::Zero();
  while (!queue_.empty()) {
    const int p = queue_.top();
    queue_.pop();
    const RBlockRow& row = r.row(p);
    // Y_p = R_pp^-T pending_p
    const Eigen::Matrix3d y =
        row.diagonal.transpose().triangularView<Eigen::Lower>().solve(pending_[p]);
    pending_[p].setZero();
    queued_[p] = 0;
    result.noalias() += y.transpose() * y;
    for (const auto& [q, block] : row.right) {
      pending_[q].noalias() -= block.transpose() * y;
      if (!queued_[q]) {
        queued_[q] = 1;
        queue_.push(q);
      }
    }
  }
  return 0.5 * (result + result.transpose());  // symmetric by construction; remove round-off
}

}  // namespace anchormap
