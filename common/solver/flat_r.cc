#include "common/solver/flat_r.h"

#include <algorithm>

namespace anchormap {
namespace {

static_assert(sizeof(Eigen::Vector3d) == 3 * sizeof(double) &&
                  sizeof(Eigen::Matrix3d) == 9 * sizeof(double),
              "the solves read vectors and blocks as plain arrays of doubles");

double* Doubles(std::vector<Eigen::Vector3d>* v) { return reinterpret_cast<double*>(v->data()); }

// The inverse of an upper triangular 3x3 block (column-major: d[i + 3 * j] is (i, j)).
std::array<double, 6> InverseUpper(const Eigen::Matrix3d& m) {
  const double* d = m.data();
  const double i00 = 1.0 / d[0], i11 = 1.0 / d[4], i22 = 1.0 / d[8];
  const double i01 = -d[3] * i00 * i11;
  const double i12 = -d[7] * i11 * i22;
  const double i02 = -(d[3] * i12 + d[6] * i22) * i00;
  return {i00, i01, i02, i11, i12, i22};
}

}  // namespace

Eigen::Matrix3d FlatR::Rounded(const Eigen::Matrix3d& block) {
  return block.cast<float>().cast<double>();
}

int FlatR::Refresh(const SparseR& r) {
  int from = 0;
  if (r.instance_id() == source_id_) {
    from = std::min(size(), r.FirstRowChangedAfter(source_revision_));
  }
  const int n = r.size();
  from = std::min(from, n);
  if (from == size() && n == size()) {
    source_revision_ = r.revision();
    return 0;
  }
  // Sized first, then filled: the source rows are scattered, the copy need not be.
  int64_t blocks = from == 0 ? 0 : row_start_[from];
  inverse_diagonals_.resize(n);
  row_start_.resize(n + 1);
  for (int p = from; p < n; ++p) {
    row_start_[p] = blocks;
    blocks += static_cast<int64_t>(r.row(p).right.size());
  }
  row_start_[n] = blocks;
  columns_.resize(blocks);
  blocks_.resize(9 * blocks);
  for (int p = from; p < n; ++p) {
    const RBlockRow& row = r.row(p);
    inverse_diagonals_[p] = InverseUpper(row.diagonal);
    int64_t k = row_start_[p];
    for (const auto& [q, block] : row.right) {
      columns_[k] = q;
      float* b = blocks_.data() + 9 * k;
      for (int i = 0; i < 9; ++i) b[i] = static_cast<float>(block.data()[i]);
      ++k;
    }
  }
  source_id_ = r.instance_id();
  source_revision_ = r.revision();
  return n - from;
}

// Both solves keep the vector's entries being worked on in locals: through the vector
// itself, the compiler must assume every store may alias the next load (and Eigen's
// 3-vector solve stored and reloaded x_p piecewise, stalling store forwarding). Blocks
// are column-major: b[i + 3 * j] is entry (i, j).
double FlatR::SolveTransposedInPlace(std::vector<Eigen::Vector3d>* v) const {
  double* x = Doubles(v);
  const int n = size();
  const int* column = columns_.data();
  const float* block = blocks_.data();
  double norm2 = 0.0;
  for (int p = 0; p < n; ++p) {
    // y = R_pp^-T x_p.
    const double* i = inverse_diagonals_[p].data();
    double* xp = x + 3 * p;
    const double y0 = i[0] * xp[0];
    const double y1 = i[1] * xp[0] + i[3] * xp[1];
    const double y2 = i[2] * xp[0] + i[4] * xp[1] + i[5] * xp[2];
    xp[0] = y0;
    xp[1] = y1;
    xp[2] = y2;
    // x_q -= R_pq^T y for the blocks right of the diagonal.
    const int64_t end = row_start_[p + 1];
    for (int64_t k = row_start_[p]; k < end; ++k) {
      const float* b = block + 9 * k;
      double* xq = x + 3 * column[k];
      xq[0] -= b[0] * y0 + b[1] * y1 + b[2] * y2;
      xq[1] -= b[3] * y0 + b[4] * y1 + b[5] * y2;
      xq[2] -= b[6] * y0 + b[7] * y1 + b[8] * y2;
    }
    norm2 += y0 * y0 + y1 * y1 + y2 * y2;
  }
  return norm2;
}

void FlatR::SolveInPlace(std::vector<Eigen::Vector3d>* v) const {
  double* x = Doubles(v);
  const int* column = columns_.data();
  const float* block = blocks_.data();
  for (int p = size() - 1; p >= 0; --p) {
    double* xp = x + 3 * p;
    double s0 = xp[0], s1 = xp[1], s2 = xp[2];
    // s -= R_pq x_q for the blocks right of the diagonal (already solved).
    const int64_t end = row_start_[p + 1];
    for (int64_t k = row_start_[p]; k < end; ++k) {
      const float* b = block + 9 * k;
      const double* xq = x + 3 * column[k];
      s0 -= b[0] * xq[0] + b[3] * xq[1] + b[6] * xq[2];
      s1 -= b[1] * xq[0] + b[4] * xq[1] + b[7] * xq[2];
      s2 -= b[2] * xq[0] + b[5] * xq[1] + b[8] * xq[2];
    }
    // x_p = R_pp^-1 s.
    const double* i = inverse_diagonals_[p].data();
    xp[0] = i[0] * s0 + i[1] * s1 + i[2] * s2;
    xp[1] = i[3] * s1 + i[4] * s2;
    xp[2] = i[5] * s2;
  }
}

}  // namespace anchormap
