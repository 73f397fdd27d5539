#include "common/solver/flat_r.h"

#include <algorithm>
#include <cstring>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace anchormap {
namespace {

static_assert(sizeof(Eigen::Vector3d) == 3 * sizeof(double) &&
                  sizeof(Eigen::Matrix3d) == 9 * sizeof(double),
              "the solves read vectors and blocks as plain arrays of doubles");

double* Doubles(std::vector<Eigen::Vector3d>* v) { return reinterpret_cast<double*>(v->data()); }

// Two doubles in one register (SSE2 on x86-64), through GCC's and Clang's vector
// extensions. The solves work on two entries of a 3-vector at once; each lane does the
// scalar code's operations in its order (no fused multiply-add on the baseline target), so
// the results are the scalar code's bits.
using Pair = double __attribute__((vector_size(16)));

// f[0], f[1], widened exactly to doubles (one 8-byte load and one conversion on SSE2,
// where GCC's generic conversion widens them one by one).
Pair Widen(const float* f) {
#if defined(__SSE2__)
  const __m128 two = _mm_loadl_pi(_mm_setzero_ps(), reinterpret_cast<const __m64*>(f));
  return reinterpret_cast<Pair>(_mm_cvtps_pd(two));
#else
  return Pair{f[0], f[1]};
#endif
}

// (f[0], f[2]) and (f[1], f[3]), widened.
void WidenCrossed(const float* f, Pair* even, Pair* odd) {
#if defined(__SSE2__)
  __m128 four = _mm_loadu_ps(f);
  four = _mm_shuffle_ps(four, four, _MM_SHUFFLE(3, 1, 2, 0));
  *even = reinterpret_cast<Pair>(_mm_cvtps_pd(four));
  *odd = reinterpret_cast<Pair>(_mm_cvtps_pd(_mm_movehl_ps(four, four)));
#else
  *even = Pair{f[0], f[2]};
  *odd = Pair{f[1], f[3]};
#endif
}

// A block's 9 floats, in the order the solves read them: rows 0-2 of columns 0 and 1 as
// pairs (R00 R01, R10 R11, R20 R21), then column 2 (R02 R12 R22). The forward solve's
// x_q0, x_q1 take the row pairs, the back solve's s0, s1 rows 0 and 1 of each column.
void StoreBlock(const Eigen::Matrix3d& m, float* b) {
  const double* d = m.data();  // column-major: d[i + 3 * j] is (i, j)
  constexpr int kFrom[9] = {0, 3, 1, 4, 2, 5, 6, 7, 8};
  for (int i = 0; i < 9; ++i) b[i] = static_cast<float>(d[kFrom[i]]);
}

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
  const bool same_source = r.instance_id() == source_id_;
  if (same_source) {
    from = std::min(size(), r.FirstRowChangedAfter(source_revision_));
  }
  const int n = r.size();
  from = std::min(from, n);
  if (from == size() && n == size()) {
    source_revision_ = r.revision();
    return 0;
  }
  // Sized first, then filled: the source rows are scattered, the copy need not be.
  const int old_n = size();
  old_start_.assign(row_start_.begin() + std::min(from, old_n), row_start_.end());
  int64_t blocks = from == 0 ? 0 : row_start_[from];
  inverse_diagonals_.resize(n);
  row_start_.resize(n + 1);
  // Rows from `from` on that did not change since the last refresh (most of them: a Givens
  // update changes the rows on its path up R) are already here, only further on by the
  // growth of the changed rows before them; they are moved within the copy, back to front,
  // instead of read again from R's scattered rows. If a row moved toward the front (a
  // changed row shrank), everything from `from` is read from R.
  bool move_unchanged = same_source;
  for (int p = from; p < n; ++p) {
    row_start_[p] = blocks;
    if (p < old_n && blocks < old_start_[p - from]) move_unchanged = false;
    blocks += static_cast<int64_t>(r.row(p).right.size());
  }
  row_start_[n] = blocks;
  columns_.resize(blocks);
  blocks_.resize(9 * blocks);
  auto copy_from_r = [&](int p) {
    const RBlockRow& row = r.row(p);
    inverse_diagonals_[p] = InverseUpper(row.diagonal);
    int64_t k = row_start_[p];
    for (const auto& [q, block] : row.right) {
      columns_[k] = q;
      StoreBlock(block, blocks_.data() + 9 * k);
      ++k;
    }
  };
  for (int p = n - 1; p >= from; --p) {
    const bool unchanged = move_unchanged && p < old_n && r.row_revision(p) <= source_revision_;
    if (!unchanged) {
      copy_from_r(p);
      continue;
    }
    const int64_t old_first = old_start_[p - from];
    const int64_t count = old_start_[p - from + 1] - old_first;
    if (old_first == row_start_[p]) continue;
    std::memmove(columns_.data() + row_start_[p], columns_.data() + old_first, count * sizeof(int));
    std::memmove(blocks_.data() + 9 * row_start_[p], blocks_.data() + 9 * old_first,
                 9 * count * sizeof(float));
  }
  source_id_ = r.instance_id();
  source_revision_ = r.revision();
  return n - from;
}

// Both solves keep the vector's entries being worked on in locals: through the vector
// itself, the compiler must assume every store may alias the next load (and Eigen's
// 3-vector solve stored and reloaded x_p piecewise, stalling store forwarding). Blocks
// are stored as StoreBlock lays them out; b[0..5] are the pairs (R00 R01), (R10 R11),
// (R20 R21), b[6..8] column 2.
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
    // x_q -= R_pq^T y for the blocks right of the diagonal: x_q0 and x_q1 as one pair.
    const Pair y0s = {y0, y0}, y1s = {y1, y1}, y2s = {y2, y2}, y01 = {y0, y1};
    const int64_t end = row_start_[p + 1];
    for (int64_t k = row_start_[p]; k < end; ++k) {
      const float* b = block + 9 * k;
      double* xq = x + 3 * column[k];
      Pair xq01;
      std::memcpy(&xq01, xq, sizeof(xq01));
      xq01 -= (Widen(b) * y0s + Widen(b + 2) * y1s) + Widen(b + 4) * y2s;
      std::memcpy(xq, &xq01, sizeof(xq01));
      // x_q2: R02 y0 and R12 y1 as one pair product, then summed in the scalar order.
      const Pair products = Widen(b + 6) * y01;
      xq[2] -= (products[0] + products[1]) + static_cast<double>(b[8]) * y2;
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
    Pair s01 = {xp[0], xp[1]};
    double s2 = xp[2];
    // s -= R_pq x_q for the blocks right of the diagonal (already solved): s0 and s1 as
    // one pair (rows 0 and 1 of each column).
    const int64_t end = row_start_[p + 1];
    for (int64_t k = row_start_[p]; k < end; ++k) {
      const float* b = block + 9 * k;
      const double* xq = x + 3 * column[k];
      const double x0 = xq[0], x1 = xq[1], x2 = xq[2];
      Pair column0, column1;
      WidenCrossed(b, &column0, &column1);
      s01 -= (column0 * Pair{x0, x0} + column1 * Pair{x1, x1}) + Widen(b + 6) * Pair{x2, x2};
      // s2: R20 x0 and R21 x1 as one pair product, then summed in the scalar order.
      const Pair products = Widen(b + 4) * Pair{x0, x1};
      s2 -= (products[0] + products[1]) + static_cast<double>(b[8]) * x2;
    }
    const double s0 = s01[0], s1 = s01[1];
    // x_p = R_pp^-1 s.
    const double* i = inverse_diagonals_[p].data();
    xp[0] = i[0] * s0 + i[1] * s1 + i[2] * s2;
    xp[1] = i[3] * s1 + i[4] * s2;
    xp[2] = i[5] * s2;
  }
}

}  // namespace anchormap
