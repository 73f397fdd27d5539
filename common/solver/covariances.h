#pragma once
// Covariance recovery from the square-root information matrix (Kaess & Dellaert, RAS
// 2009; docs/METHOD.md section 6), by 3x3 blocks. With Sigma = (R^T R)^-1 and R Sigma =
// R^-T (block lower triangular, diagonal blocks R_ii^-T):
//
//   Sigma_ll = R_ll^-1 ( R_ll^-T - sum_{j>l, R_lj != 0} R_lj Sigma_jl )
//   Sigma_il = -R_ii^-1 sum_{j>i, R_ij != 0} R_ij Sigma_jl              (i < l)
//
// Only the entries a query needs are computed, and memoised. Entries outside R's
// pattern work too, at a higher cost. The object holds its own reference to R, so a
// snapshot can be queried off the solver's thread while the solver moves on.

#include <cstdint>
#include <functional>
#include <memory>
#include <queue>
#include <unordered_map>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "common/solver/sparse_r.h"

namespace anchormap {

// The memo of computed blocks: open addressing with linear probing on a 64-bit id. Each
// entry computed looks up every block its row depends on; std::unordered_map's node per
// entry and bucket walk made those lookups most of the server's CPU at 100 robots.
class CovarianceBlockMemo {
 public:
  const Eigen::Matrix3d* Find(uint64_t id) const {
    if (keys_.empty()) return nullptr;
    for (size_t slot = Slot(id);; slot = (slot + 1) & mask_) {
      if (keys_[slot] == id) return &values_[slot];
      if (keys_[slot] == kEmpty) return nullptr;
    }
  }
  // Precondition: id not present. Pointers from Find are invalid afterwards.
  void Insert(uint64_t id, const Eigen::Matrix3d& value);
  size_t size() const { return size_; }

 private:
  static constexpr uint64_t kEmpty = ~uint64_t{0};
  size_t Slot(uint64_t id) const {
    return static_cast<size_t>((id * 0x9E3779B97F4A7C15ull) >> shift_);  // Fibonacci hashing
  }
  void Grow();

  std::vector<uint64_t> keys_;
  std::vector<Eigen::Matrix3d> values_;
  size_t size_ = 0;
  size_t mask_ = 0;
  int shift_ = 64;
};

class CovarianceRecovery {
 public:
  explicit CovarianceRecovery(std::shared_ptr<const SparseR> r) : r_(std::move(r)) {}

  // Sigma_il, the 3x3 covariance block between positions i and l.
  Eigen::Matrix3d Block(int i, int l);
  // The joint covariance of several positions, blocks in the order given.
  Eigen::MatrixXd Joint(const std::vector<int>& positions);
  // Entries computed so far (memoised).
  size_t memoised() const { return memo_.size(); }

 private:
  // Computes the canonical entry (i <= l) and everything it depends on.
  const Eigen::Matrix3d& Canonical(int i, int l);
  const Eigen::Matrix3d* Find(int i, int l) const { return memo_.Find(Id(i, l)); }
  uint64_t Id(int i, int l) const {
    return static_cast<uint64_t>(i) * static_cast<uint64_t>(r_->size()) + static_cast<uint64_t>(l);
  }

  std::shared_ptr<const SparseR> r_;
  CovarianceBlockMemo memo_;
  // Scratch of Canonical, kept between calls: the entries still to compute, and the
  // blocks one entry depends on.
  std::vector<std::pair<int, int>> stack_;
  std::vector<const Eigen::Matrix3d*> inputs_;
};

// J Sigma J^T for a few positions of R, without Sigma's blocks: with Sigma = R^-1 R^-T,
//
//   J Sigma J^T = Y^T Y,   Y = R^-T J^T   (R^T Y = J^T: one forward substitution),
//
// and Y is non-zero only on the ancestors of the positions in R's elimination tree. The
// cost is the non-zeros of R on those rows times J's rows (3): linear in the size of the
// dense corner that anchors and latest poses form at the bottom of R, where the block
// recursion (CovarianceRecovery above) needs every pair of the corner's positions and costs its
// cube. At 100 robots in one group that corner reached 300 positions, and the gates'
// joint covariances took 85 % of the server's CPU (docs/ARCHITECTURE.md, "Server cost at
// scale"). Exact; the round-off differs from the recursion's.
class CovarianceProjection {
 public:
  // J Sigma J^T, J = [J_1 ... J_k] with J_s (3x3) acting on position positions[s]
  // (positions may repeat: their J_s add up). Scratch space is kept between calls; `r` must
  // not change during a call. A query asked again of the same R (its instance and
  // revision) with the same positions and Jacobians, bit for bit, is answered from a memo
  // with the bits it got the first time: the gates of one keyframe and the pairs of a
  // consistency check ask some pairs several times between two updates (14 % of the
  // queries late in a 20-robot run), each a walk through R's wide bottom rows.
  Eigen::Matrix3d Compute(const SparseR& r, const std::vector<int>& positions,
                          const std::vector<Eigen::Matrix3d>& jacobians);
  // The same solve, stopped once `enough` holds for the sum so far (asked before the first
  // row and then every few rows). Every row adds Y_p^T Y_p, so each partial sum is a lower
  // bound of J Sigma J^T in the positive semidefinite order: a gate whose test only gets
  // easier to pass as the covariance grows (a Mahalanobis distance under it, at most a
  // bound) passes under the exact covariance once it passes under a partial one. Returns
  // false and the partial sum when it stopped early, true and Compute's result (its bits,
  // its memo) otherwise.
  using Enough = std::function<bool(const Eigen::Matrix3d& covariance_so_far)>;
  bool ComputeUntil(const SparseR& r, const std::vector<int>& positions,
                    const std::vector<Eigen::Matrix3d>& jacobians, const Enough& enough,
                    Eigen::Matrix3d* result);
  // One query of ComputeSideBySide: J = [J_1 ... J_k] on `positions`, as Compute takes them.
  struct Query {
    std::vector<int> positions;
    std::vector<Eigen::Matrix3d> jacobians;
  };
  // Each query's J Sigma J^T, the bits Compute gives for it (and its memo: queries already
  // remembered are answered from it, the others remembered), in one walk: the queries'
  // forward substitutions run side by side over the union of their ancestors' rows, each
  // reading a row of R once for all of them. The solve is bound by reading R's wide bottom
  // rows (the block loads miss the cache), so queries known together, e.g. a keyframe's
  // loop-closure candidates whose gate is decided without their covariance, cost little
  // more than one.
  std::vector<Eigen::Matrix3d> ComputeSideBySide(const SparseR& r,
                                                 const std::vector<Query>& queries);
  // Each position's marginal covariance (J = I), the bits Compute(r, {p}, {I}) gives for
  // each, side by side (ComputeSideBySide). The anchors' covariances, published twice per
  // second of data, have long paths that share most rows (late in a 20-robot run, 44k
  // blocks each: a quarter of the projections' work).
  std::vector<Eigen::Matrix3d> Marginals(const SparseR& r, const std::vector<int>& positions);
  // Queries answered from the memo, and those computed.
  int64_t memo_hits() const { return memo_hits_; }
  int64_t computed() const { return computed_; }
  // ComputeUntil's solves that stopped early.
  int64_t stopped_early() const { return stopped_early_; }

 private:
  // The forward substitution; with `enough`, stopped as ComputeUntil says (then false).
  bool Solve(const SparseR& r, const std::vector<int>& positions,
             const std::vector<Eigen::Matrix3d>& jacobians, const Enough* enough,
             Eigen::Matrix3d* result);
  // Checks the arguments and makes the memo that of r's current revision.
  void Prepare(const SparseR& r, const std::vector<int>& positions,
               const std::vector<Eigen::Matrix3d>& jacobians);
  // The memo's entry: the query's positions and Jacobians, compared in full (the hash only
  // finds the candidates), and its result.
  struct Remembrance {
    Query query;
    Eigen::Matrix3d result;
  };
  static uint64_t HashOf(const std::vector<int>& positions,
                         const std::vector<Eigen::Matrix3d>& jacobians);
  const Eigen::Matrix3d* Remembered(uint64_t hash, const std::vector<int>& positions,
                                    const std::vector<Eigen::Matrix3d>& jacobians) const;

  // By position: the right-hand side still to solve (J^T's block minus what earlier rows
  // pushed), and whether the position is in the queue.
  std::vector<Eigen::Matrix3d> pending_;
  std::vector<char> queued_;
  std::priority_queue<int, std::vector<int>, std::greater<int>> queue_;
  // The memo, for R's (instance, revision) of memo_r_ only.
  std::pair<uint64_t, uint64_t> memo_r_{0, 0};
  bool memo_valid_ = false;
  std::unordered_multimap<uint64_t, size_t> memo_index_;
  std::vector<Remembrance> memo_;
  int64_t memo_hits_ = 0;
  int64_t computed_ = 0;
  int64_t stopped_early_ = 0;
  // ComputeSideBySide's work space: by position its slot (-1: none) and by slot the
  // queries' pending blocks (one per query solved) and which of them are queued.
  std::vector<int> slot_;
  std::vector<Eigen::Matrix3d> slot_pending_;
  std::vector<char> slot_queued_;
};

}  // namespace anchormap
