#include "common/solver/covariances.h"

#include <cstring>
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

uint64_t CovarianceProjection::HashOf(const std::vector<int>& positions,
                                      const std::vector<Eigen::Matrix3d>& jacobians) {
  // FNV-1a over the positions and the Jacobians' bits.
  uint64_t hash = 1469598103934665603ull;
  const auto mix = [&hash](const void* data, size_t bytes) {
    const auto* c = static_cast<const unsigned char*>(data);
    for (size_t i = 0; i < bytes; ++i) hash = (hash ^ c[i]) * 1099511628211ull;
  };
  for (size_t s = 0; s < positions.size(); ++s) {
    mix(&positions[s], sizeof(int));
    mix(jacobians[s].data(), 9 * sizeof(double));
  }
  return hash;
}

const Eigen::Matrix3d* CovarianceProjection::Remembered(
    uint64_t hash, const std::vector<int>& positions,
    const std::vector<Eigen::Matrix3d>& jacobians) const {
  const auto [first, last] = memo_index_.equal_range(hash);
  for (auto it = first; it != last; ++it) {
    const Query& query = memo_[it->second].query;
    if (query.positions != positions) continue;
    bool same = true;
    for (size_t s = 0; s < jacobians.size() && same; ++s) {
      // Bit for bit (memcmp): the memo must give what the solve gives for these bits.
      same = std::memcmp(query.jacobians[s].data(), jacobians[s].data(), 9 * sizeof(double)) == 0;
    }
    if (same) return &memo_[it->second].result;
  }
  return nullptr;
}

void CovarianceProjection::Prepare(const SparseR& r, const std::vector<int>& positions,
                                   const std::vector<Eigen::Matrix3d>& jacobians) {
  if (positions.size() != jacobians.size()) {
    throw std::invalid_argument("CovarianceProjection: one Jacobian block per position");
  }
  for (int p : positions) {
    if (p < 0 || p >= r.size()) throw std::out_of_range("CovarianceProjection: position outside R");
  }
  const std::pair<uint64_t, uint64_t> version{r.instance_id(), r.revision()};
  if (!memo_valid_ || memo_r_ != version) {
    memo_r_ = version;
    memo_valid_ = true;
    memo_index_.clear();
    memo_.clear();
  }
}

Eigen::Matrix3d CovarianceProjection::Compute(const SparseR& r, const std::vector<int>& positions,
                                              const std::vector<Eigen::Matrix3d>& jacobians) {
  Eigen::Matrix3d result;
  ComputeUntil(r, positions, jacobians, nullptr, &result);
  return result;
}

bool CovarianceProjection::ComputeUntil(const SparseR& r, const std::vector<int>& positions,
                                        const std::vector<Eigen::Matrix3d>& jacobians,
                                        const Enough& enough, Eigen::Matrix3d* result) {
  Prepare(r, positions, jacobians);
  const uint64_t hash = HashOf(positions, jacobians);
  if (const Eigen::Matrix3d* known = Remembered(hash, positions, jacobians)) {
    ++memo_hits_;
    *result = *known;
    return true;
  }
  if (!Solve(r, positions, jacobians, enough ? &enough : nullptr, result)) {
    ++stopped_early_;
    return false;
  }
  ++computed_;
  memo_index_.emplace(hash, memo_.size());
  memo_.push_back({{positions, jacobians}, *result});
  return true;
}

bool CovarianceProjection::Solve(const SparseR& r, const std::vector<int>& positions,
                                 const std::vector<Eigen::Matrix3d>& jacobians,
                                 const Enough* enough, Eigen::Matrix3d* out) {
  const int n = r.size();
  if (static_cast<int>(pending_.size()) < n) {
    pending_.resize(n, Eigen::Matrix3d::Zero());
    queued_.resize(n, 0);
  }
  // Rows between two asks of `enough`: a row late in a large map holds ~100 blocks, and
  // one ask costs about one block's product.
  constexpr int kRowsPerAsk = 8;
  Eigen::Matrix3d result = Eigen::Matrix3d::Zero();
  if (enough != nullptr && (*enough)(result)) {
    *out = result;
    return false;
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
  int rows = 0;
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
    if (enough != nullptr && ++rows % kRowsPerAsk == 0 && !queue_.empty() &&
        (*enough)(0.5 * (result + result.transpose()))) {
      while (!queue_.empty()) {  // leave the work space clean for the next query
        pending_[queue_.top()].setZero();
        queued_[queue_.top()] = 0;
        queue_.pop();
      }
      *out = 0.5 * (result + result.transpose());
      return false;
    }
  }
  *out = 0.5 * (result + result.transpose());  // symmetric by construction; remove round-off
  return true;
}

std::vector<Eigen::Matrix3d> CovarianceProjection::ComputeSideBySide(
    const SparseR& r, const std::vector<Query>& queries) {
  std::vector<Eigen::Matrix3d> results(queries.size());
  std::vector<uint64_t> hashes(queries.size());
  std::vector<size_t> solved;  // the queries not remembered, solved below
  for (size_t g = 0; g < queries.size(); ++g) {
    Prepare(r, queries[g].positions, queries[g].jacobians);
    hashes[g] = HashOf(queries[g].positions, queries[g].jacobians);
    if (const Eigen::Matrix3d* known =
            Remembered(hashes[g], queries[g].positions, queries[g].jacobians)) {
      ++memo_hits_;
      results[g] = *known;
    } else {
      solved.push_back(g);
    }
  }
  const size_t k = solved.size();
  if (k == 0) return results;
  const int n = r.size();
  if (static_cast<int>(slot_.size()) < n) slot_.resize(n, -1);
  slot_pending_.clear();
  slot_queued_.clear();
  std::vector<int> used;  // positions given a slot, in the order they got it
  // A row's slot, made (and the row queued) the first time a query's solve reaches it.
  const auto slot_of = [&](int p) {
    if (slot_[p] < 0) {
      slot_[p] = static_cast<int>(used.size());
      used.push_back(p);
      slot_pending_.resize(slot_pending_.size() + k, Eigen::Matrix3d::Zero());
      slot_queued_.resize(slot_queued_.size() + k, 0);
      queue_.push(p);
    }
    return static_cast<size_t>(slot_[p]);
  };
  for (size_t g = 0; g < k; ++g) {
    const Query& query = queries[solved[g]];
    for (size_t s = 0; s < query.positions.size(); ++s) {
      const size_t slot = slot_of(query.positions[s]);
      slot_pending_[slot * k + g] += query.jacobians[s].transpose();  // as Solve adds J^T
      slot_queued_[slot * k + g] = 1;
    }
  }
  // Each query's solve is Solve's: the same rows in the same (ascending) order, the same
  // operations on its own blocks; they only share the walk.
  std::vector<Eigen::Matrix3d> sums(k, Eigen::Matrix3d::Zero());
  std::vector<Eigen::Matrix3d> y(k);
  std::vector<size_t> active;
  while (!queue_.empty()) {
    const int p = queue_.top();
    queue_.pop();
    const RBlockRow& row = r.row(p);
    const size_t s = static_cast<size_t>(slot_[p]);
    active.clear();
    for (size_t g = 0; g < k; ++g) {
      if (!slot_queued_[s * k + g]) continue;
      active.push_back(g);
      y[g] =
          row.diagonal.transpose().triangularView<Eigen::Lower>().solve(slot_pending_[s * k + g]);
      sums[g].noalias() += y[g].transpose() * y[g];
    }
    for (const auto& [q, block] : row.right) {
      const size_t sq = slot_of(q);
      for (size_t g : active) {
        slot_pending_[sq * k + g].noalias() -= block.transpose() * y[g];
        slot_queued_[sq * k + g] = 1;
      }
    }
  }
  for (int p : used) slot_[p] = -1;
  for (size_t g = 0; g < k; ++g) {
    const size_t asked = solved[g];
    results[asked] = 0.5 * (sums[g] + sums[g].transpose());  // as Solve
    ++computed_;
    // A query asked twice in one call is solved twice and remembered once.
    if (Remembered(hashes[asked], queries[asked].positions, queries[asked].jacobians) == nullptr) {
      memo_index_.emplace(hashes[asked], memo_.size());
      memo_.push_back({queries[asked], results[asked]});
    }
  }
  return results;
}

std::vector<Eigen::Matrix3d> CovarianceProjection::Marginals(const SparseR& r,
                                                             const std::vector<int>& positions) {
  std::vector<Query> queries;
  queries.reserve(positions.size());
  for (int p : positions) queries.push_back({{p}, {Eigen::Matrix3d::Identity()}});
  return ComputeSideBySide(r, queries);
}

}  // namespace anchormap
