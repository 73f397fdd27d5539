#pragma once
// The factors of a smoother linearised at its current estimate, kept between gradient
// passes of the correction (incremental_gradient.h). An entry is recomputed only when one
// of its variables' values differs in any bit from the value it was last computed at, so
// the cache is a pure function of the estimate: a smoother rebuilt from a snapshot (which
// starts with an empty cache) computes the same bits, and a pass costs the factors whose
// variables moved, not the map.
//
// Entries are packed in one array, each only as long as its factor's keys need (a between
// factor's is 21 doubles, where a LinearizedFactor has room for four Jacobians: 40): the
// gradient passes and the conjugate gradients' J^T J p stream every entry, so on a large
// map the cache's size is what they wait for.

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/solver/factor.h"

namespace anchormap {

// A factor linearised at a pass's values, read in place from the cache: the whitened
// error S e, then the Jacobians S J_k (column-major), as LinearizedFactor holds them.
class LinearizedView {
 public:
  LinearizedView() = default;
  LinearizedView(const double* data, int num_keys) : data_(data), num_keys_(num_keys) {}
  int num_keys() const { return num_keys_; }
  Eigen::Map<const Eigen::Vector3d> whitened_error() const {
    return Eigen::Map<const Eigen::Vector3d>(data_);
  }
  Eigen::Map<const Eigen::Matrix3d> jacobian(int k) const {
    return Eigen::Map<const Eigen::Matrix3d>(data_ + 3 + 9 * k);
  }

 private:
  const double* data_ = nullptr;
  int num_keys_ = 0;
};

class LinearizationCache {
 public:
  // Starts a pass over factor ids below `num_factors` at `values` (by variable index):
  // remembers which variables moved since the last pass (every one on the first). Entries
  // returned by At() stay where they are until the next pass.
  void BeginPass(const std::vector<Pose2>& values, int64_t num_factors);

  // Factor `id` over variables `vars` linearised at the pass's values: the cached entry
  // if none of its variables moved and it was computed in the previous pass, else a new one.
  // The view is valid until the next call of At() (which may grow the store). Also its
  // gradient terms J_k^T e (3 doubles per key) at `terms` and |e|^2 at `squared`
  // (PackedGradientTerms), computed with the entry when it is linearised.
  LinearizedView At(int64_t id, const Factor& factor, const int* vars, int num_vars, double* terms,
                    double* squared);
  // Factor `id` is not part of this pass: its entry is dropped (its variables may move
  // unseen before it is back).
  void Skip(int64_t id);
  void Clear();

  // Factor `id`'s entry as the last At() left it; valid until the next At().
  LinearizedView entry(int64_t id) const {
    return LinearizedView(store_.data() + offset_[id], num_keys_[id]);
  }
  // By variable: whether its value differs from the previous pass (every one on the first).
  const std::vector<char>& moved() const { return moved_; }

  // Work counters: passes and factors linearised by them (cache misses).
  int64_t passes() const { return passes_; }
  int64_t linearized() const { return linearized_; }

 private:
  std::vector<Pose2> values_;  // by variable: the values of the current pass
  // By variable: CosSin of its value, once per moved variable instead of once per factor.
  std::vector<CosSin> rotations_;
  std::vector<char> moved_;  // by variable: differs from the previous pass
  // The entries, packed: factor id's at offset_[id] (-1 before its first), 3 + 9 x
  // num_keys_[id] doubles (a factor's keys never change).
  std::vector<double> store_;
  std::vector<int64_t> offset_;          // by factor id
  std::vector<unsigned char> num_keys_;  // by factor id
  std::vector<char> valid_;              // by factor id
  int64_t passes_ = 0;
  int64_t linearized_ = 0;
};

}  // namespace anchormap
