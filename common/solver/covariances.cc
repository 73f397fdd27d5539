#include "common/solver/covariances.h"

#include <utility>

#include <Eigen/Dense>

namespace anchormap {

const Eigen::Matrix3d* CovarianceRecovery::Find(int i, int l) const {
  auto it = memo_.find(Id(i, l));
  return it == memo_.end() ? nullptr : &it->second;
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
  std::vector<std::pair<int, int>> stack = {{i0, l0}};
  while (!stack.empty()) {
    const auto [i, l] = stack.back();
    if (Find(i, l)) {
      stack.pop_back();
      continue;
    }
    const RBlockRow& row = r_->row(i);
    bool ready = true;
    for (const auto& [j, block] : row.right) {
      const int a = std::min(j, l), b = std::max(j, l);
      if (!Find(a, b)) {
        stack.emplace_back(a, b);
        ready = false;
      }
    }
    if (!ready) continue;

    // sum_j R_ij Sigma_jl, with Sigma_jl = Sigma_lj^T when j > l.
    Eigen::Matrix3d sum = Eigen::Matrix3d::Zero();
    for (const auto& [j, block] : row.right) {
      if (j <= l) {
        sum.noalias() += block * *Find(j, l);
      } else {
        sum.noalias() += block * Find(l, j)->transpose();
      }
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
    memo_.emplace(Id(i, l), value);
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

}  // namespace anchormap
