#include "common/solver/flat_r.h"

#include <algorithm>
#include <cstring>

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif

namespace anchormap {
namespace {

static_assert(sizeof(Eigen::Vector3d) == 3 * sizeof(double) &&
                  sizeof(Eigen::Matrix3d) == 9 * sizeof(double),
              "the solves read vectors and blocks as plain arrays of doubles");

double* Doubles(std::vector<Eigen::Vector3d>* v) { return reinterpret_cast<double*>(v->data()); }

// Four doubles, through GCC's and Clang's vector extensions; each lane does the scalar
// code's operations in its order. A block's row or column is lanes 0-2; lane 3 is unused.
using Lanes = double __attribute__((vector_size(32)));
using FloatLanes = float __attribute__((vector_size(16)));

// f[0..3] widened exactly to doubles (f[3] is the block's next row's first entry, the next
// block's, or the array's zero padding: it only ever lands in lane 3). Through a pointer: a
// 32-byte vector returned by value has another ABI where AVX is not enabled.
inline __attribute__((always_inline)) void Widen(const float* f, Lanes* out) {
  FloatLanes four;
  std::memcpy(&four, f, sizeof(four));
  *out = __builtin_convertvector(four, Lanes);
}

// An AVX2 build of both solves beside the portable one, chosen at run time (one binary for
// every x86-64 CPU): the same operations per lane in the same order, in registers of four
// doubles, where GCC's generic code widens floats two at a time. No build fuses a product
// into a sum (the AVX2 target has no FMA, and this file is compiled with -ffp-contract=off),
// so both give the plain scalar code's bits (flat_r_test.cc).
#if defined(__x86_64__) && defined(__GNUC__)
#define ANCHORMAP_FLAT_R_AVX2 1
bool UseAvx2() {
  static const bool has = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") != 0;
  }();
  return has && FlatR::VectorSolvesAllowed().load(std::memory_order_relaxed);
}
#endif

// The inverse of an upper triangular 3x3 block (column-major: d[i + 3 * j] is (i, j)).
std::array<double, 6> InverseUpper(const Eigen::Matrix3d& m) {
  const double* d = m.data();
  const double i00 = 1.0 / d[0], i11 = 1.0 / d[4], i22 = 1.0 / d[8];
  const double i01 = -d[3] * i00 * i11;
  const double i12 = -d[7] * i11 * i22;
  const double i02 = -(d[3] * i12 + d[6] * i22) * i00;
  return {i00, i01, i02, i11, i12, i22};
}

// The solves' arguments: FlatR's arrays.
struct Arrays {
  int n;
  const std::array<double, 6>* inverse_diagonals;
  const int64_t* row_start;
  const int* column;
  const float* blocks;  // row-major
};

// y = R_pp^-T x_p (x_p: 3 doubles).
inline __attribute__((always_inline)) void SolveDiagonalTransposed(const double* i,
                                                                   const double* xp, double y[3]) {
  y[0] = i[0] * xp[0];
  y[1] = i[1] * xp[0] + i[3] * xp[1];
  y[2] = i[2] * xp[0] + i[4] * xp[1] + i[5] * xp[2];
}

// x_p = R_pp^-1 s.
inline __attribute__((always_inline)) void SolveDiagonal(const double* i, double s0, double s1,
                                                         double s2, double* xp) {
  xp[0] = i[0] * s0 + i[1] * s1 + i[2] * s2;
  xp[1] = i[3] * s1 + i[4] * s2;
  xp[2] = i[5] * s2;
}

// v <- R^-T in with x the work space (4 doubles per entry, 32-byte aligned; `in` is read
// into it first, so it may be v); returns |R^-T in|^2. Row p's y goes to v as soon as it is known
// (nothing reads v_p after that). x_q -= R_pq^T y: entry j of x_q less (R_0j y0 + R_1j y1) + R_2j
// y2, the block's rows as lanes j. Lane 3's y is zero, so x_q's lane 3 stays zero.
double ForwardSolve(const Arrays& a, const double* in, double* v, double* x) {
  for (int p = 0; p < a.n; ++p) {
    const Lanes entry = {in[3 * p], in[3 * p + 1], in[3 * p + 2], 0.0};
    std::memcpy(x + 4 * p, &entry, sizeof(entry));
  }
  double norm2 = 0.0;
  for (int p = 0; p < a.n; ++p) {
    double y[3];
    SolveDiagonalTransposed(a.inverse_diagonals[p].data(), x + 4 * p, y);
    std::memcpy(v + 3 * p, y, sizeof(y));
    const Lanes y0 = {y[0], y[0], y[0], 0.0}, y1 = {y[1], y[1], y[1], 0.0};
    const Lanes y2 = {y[2], y[2], y[2], 0.0};
    for (int64_t k = a.row_start[p]; k < a.row_start[p + 1]; ++k) {
      const float* b = a.blocks + 9 * k;
      double* xq = x + 4 * static_cast<int64_t>(a.column[k]);
      Lanes value, row0, row1, row2;
      std::memcpy(&value, xq, sizeof(value));
      Widen(b, &row0);
      Widen(b + 3, &row1);
      Widen(b + 6, &row2);
      value -= (row0 * y0 + row1 * y1) + row2 * y2;
      std::memcpy(xq, &value, sizeof(value));
    }
    norm2 += y[0] * y[0] + y[1] * y[1] + y[2] * y[2];
  }
  return norm2;
}

// v <- R^-1 v. s_p less R_pq x_q: entry i of s less (R_i0 x0 + R_i1 x1) + R_i2 x2, the
// block's columns (gathered from its rows) as lanes i.
void BackSolve(const Arrays& a, double* v) {
  for (int p = a.n - 1; p >= 0; --p) {
    double* xp = v + 3 * p;
    Lanes s = {xp[0], xp[1], xp[2], 0.0};
    for (int64_t k = a.row_start[p]; k < a.row_start[p + 1]; ++k) {
      const float* b = a.blocks + 9 * k;
      const double* xq = v + 3 * static_cast<int64_t>(a.column[k]);
      const Lanes x0 = {xq[0], xq[0], xq[0], xq[0]}, x1 = {xq[1], xq[1], xq[1], xq[1]};
      const Lanes x2 = {xq[2], xq[2], xq[2], xq[2]};
      const Lanes column0 = {b[0], b[3], b[6], 0.0}, column1 = {b[1], b[4], b[7], 0.0};
      const Lanes column2 = {b[2], b[5], b[8], 0.0};
      s -= (column0 * x0 + column1 * x1) + column2 * x2;
    }
    SolveDiagonal(a.inverse_diagonals[p].data(), s[0], s[1], s[2], xp);
  }
}

#ifdef ANCHORMAP_FLAT_R_AVX2
// The same two solves with AVX2 registers (see above).
__attribute__((target("avx2"))) inline __m256d WidenAvx2(const float* f) {
  return _mm256_cvtps_pd(_mm_loadu_ps(f));
}

__attribute__((target("avx2"))) double ForwardSolveAvx2(const Arrays& arrays, const double* in,
                                                        double* v, double* x) {
  const Arrays a = arrays;  // in registers: the stores through v and x could alias it
  for (int p = 0; p < a.n; ++p) {
    _mm256_store_pd(x + 4 * p, _mm256_setr_pd(in[3 * p], in[3 * p + 1], in[3 * p + 2], 0.0));
  }
  double norm2 = 0.0;
  for (int p = 0; p < a.n; ++p) {
    double y[3];
    SolveDiagonalTransposed(a.inverse_diagonals[p].data(), x + 4 * p, y);
    std::memcpy(v + 3 * p, y, sizeof(y));
    const __m256d y0 = _mm256_setr_pd(y[0], y[0], y[0], 0.0);
    const __m256d y1 = _mm256_setr_pd(y[1], y[1], y[1], 0.0);
    const __m256d y2 = _mm256_setr_pd(y[2], y[2], y[2], 0.0);
    const int64_t end = a.row_start[p + 1];
    for (int64_t k = a.row_start[p]; k < end; ++k) {
      const float* b = a.blocks + 9 * k;
      double* xq = x + 4 * static_cast<int64_t>(a.column[k]);
      const __m256d sum = _mm256_add_pd(
          _mm256_add_pd(_mm256_mul_pd(WidenAvx2(b), y0), _mm256_mul_pd(WidenAvx2(b + 3), y1)),
          _mm256_mul_pd(WidenAvx2(b + 6), y2));
      _mm256_store_pd(xq, _mm256_sub_pd(_mm256_load_pd(xq), sum));
    }
    norm2 += y[0] * y[0] + y[1] * y[1] + y[2] * y[2];
  }
  return norm2;
}

__attribute__((target("avx2"))) void BackSolveAvx2(const Arrays& arrays, double* v) {
  const Arrays a = arrays;  // in registers: the stores through v could alias it
  for (int p = a.n - 1; p >= 0; --p) {
    double* xp = v + 3 * p;
    __m256d s = _mm256_setr_pd(xp[0], xp[1], xp[2], 0.0);
    const int64_t end = a.row_start[p + 1];
    for (int64_t k = a.row_start[p]; k < end; ++k) {
      const float* b = a.blocks + 9 * k;
      const double* xq = v + 3 * static_cast<int64_t>(a.column[k]);
      // The block's columns from its rows: entries (0, 3, 6) and (1, 4, 7) of its first
      // eight by one permutation, (2, 5, 8) by one shuffle of two overlapping loads.
      const __m256 columns01 =
          _mm256_permutevar8x32_ps(_mm256_loadu_ps(b), _mm256_setr_epi32(0, 3, 6, 6, 1, 4, 7, 7));
      const __m128 column2 =
          _mm_shuffle_ps(_mm_loadu_ps(b + 2), _mm_loadu_ps(b + 5), _MM_SHUFFLE(3, 3, 3, 0));
      const __m256d sum = _mm256_add_pd(
          _mm256_add_pd(_mm256_mul_pd(_mm256_cvtps_pd(_mm256_castps256_ps128(columns01)),
                                      _mm256_broadcast_sd(xq)),
                        _mm256_mul_pd(_mm256_cvtps_pd(_mm256_extractf128_ps(columns01, 1)),
                                      _mm256_broadcast_sd(xq + 1))),
          _mm256_mul_pd(_mm256_cvtps_pd(column2), _mm256_broadcast_sd(xq + 2)));
      s = _mm256_sub_pd(s, sum);
    }
    alignas(32) double lanes[4];
    _mm256_store_pd(lanes, s);
    SolveDiagonal(a.inverse_diagonals[p].data(), lanes[0], lanes[1], lanes[2], xp);
  }
}
#endif

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
  constexpr int kPadding = 3;
  row_major_.resize(9 * blocks + kPadding);
  auto copy_from_r = [&](int p) {
    const RBlockRow& row = r.row(p);
    inverse_diagonals_[p] = InverseUpper(row.diagonal);
    int64_t k = row_start_[p];
    for (const auto& [q, block] : row.right) {
      columns_[k] = q;
      const double* d = block.data();  // column-major: d[i + 3 * j] is (i, j)
      float* by_row = row_major_.data() + 9 * k;
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) by_row[3 * i + j] = static_cast<float>(d[i + 3 * j]);
      }
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
    std::memmove(row_major_.data() + 9 * row_start_[p], row_major_.data() + 9 * old_first,
                 9 * count * sizeof(float));
  }
  std::fill(row_major_.end() - kPadding, row_major_.end(), 0.0f);
  source_id_ = r.instance_id();
  source_revision_ = r.revision();
  return n - from;
}

std::atomic<bool>& FlatR::VectorSolvesAllowed() {
  static std::atomic<bool> allowed{true};
  return allowed;
}

double FlatR::SolveTransposedInPlace(std::vector<Eigen::Vector3d>* v) const {
  return SolveTransposed(*v, v);
}

double FlatR::SolveTransposed(const std::vector<Eigen::Vector3d>& v,
                              std::vector<Eigen::Vector3d>* y) const {
  const Arrays a{size(), inverse_diagonals_.data(), row_start_.data(), columns_.data(),
                 row_major_.data()};
  y->resize(v.size());
  padded_.resize(a.n + 1);  // never empty: its data() is a valid address
  double* x = padded_.data()->x;
  const double* in = reinterpret_cast<const double*>(v.data());
#ifdef ANCHORMAP_FLAT_R_AVX2
  if (UseAvx2()) return ForwardSolveAvx2(a, in, Doubles(y), x);
#endif
  return ForwardSolve(a, in, Doubles(y), x);
}

void FlatR::SolveInPlace(std::vector<Eigen::Vector3d>* v) const {
  const Arrays a{size(), inverse_diagonals_.data(), row_start_.data(), columns_.data(),
                 row_major_.data()};
#ifdef ANCHORMAP_FLAT_R_AVX2
  if (UseAvx2()) return BackSolveAvx2(a, Doubles(v));
#endif
  BackSolve(a, Doubles(v));
}

}  // namespace anchormap
