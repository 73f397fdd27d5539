#include "common/solver/path_solve.h"

#include <algorithm>
#include <functional>

#include <Eigen/Dense>

namespace anchormap {

double PathSolve::SquaredNorm(const SparseR& r,
                              const std::vector<std::pair<int, Eigen::Vector3d>>& g,
                              double stop_above) {
  const int n = r.size();
  if (static_cast<int>(value_.size()) < n) {
    value_.resize(n, Eigen::Vector3d::Zero());
    queued_.resize(n, 0);
  }
  const auto later = std::greater<int>();
  auto queue = [&](int p) {
    if (queued_[p]) return;
    queued_[p] = 1;
    heap_.push_back(p);
    std::push_heap(heap_.begin(), heap_.end(), later);
  };
  heap_.clear();
  for (const auto& [p, v] : g) {
    value_[p] += v;
    queue(p);
  }
  // In ascending order: a row's value is final once every row referencing its column (all
  // before it) has been solved.
  double norm2 = 0.0;
  rows_solved_ = 0;
  while (!heap_.empty() && norm2 <= stop_above) {
    std::pop_heap(heap_.begin(), heap_.end(), later);
    const int p = heap_.back();
    heap_.pop_back();
    const RBlockRow& row = r.row(p);
    const Eigen::Vector3d y =
        row.diagonal.triangularView<Eigen::Upper>().transpose().solve(value_[p]);
    value_[p].setZero();
    queued_[p] = 0;
    ++rows_solved_;
    norm2 += y.squaredNorm();
    for (const auto& [q, block] : row.right) {
      value_[q].noalias() -= block.transpose() * y;
      queue(q);
    }
  }
  for (int p : heap_) {  // stopped early
    value_[p].setZero();
    queued_[p] = 0;
  }
  return norm2;
}

}  // namespace anchormap
