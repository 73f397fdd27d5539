#include "common/solver/block_givens.h"

#include <cmath>

// Two builds of the kernel, chosen at load time by the CPU (GCC's function multiversioning;
// needs ifunc, so glibc on x86-64 only). Elsewhere the baseline build is the only one.
// Where the CPU has AVX-512, the AVX2 + FMA build applies the rotations in eight columns at
// a time (ApplyRotationsAvx512): the same fused operations per entry as the AVX2 build's,
// so the same bits (block_givens_test.cc compares them).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && defined(__GLIBC__)
#define ANCHORMAP_CPU_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#define ANCHORMAP_GIVENS_AVX512 1
#include <immintrin.h>
#else
#define ANCHORMAP_CPU_CLONES
#endif

namespace anchormap {
namespace {

// The nine rotations on `n` columns of the six rows, one column at a time, all in
// registers. Separate restrict parameters: the rows never overlap, and saying so lets the
// compiler vectorise across columns.
inline __attribute__((always_inline)) void ApplyRotations(
    const double* c, const double* s, double* __restrict r0, double* __restrict r1,
    double* __restrict r2, double* __restrict r3, double* __restrict r4, double* __restrict r5,
    int n) {
  for (int j = 0; j < n; ++j) {
    double v0 = r0[j], v1 = r1[j], v2 = r2[j], v3 = r3[j], v4 = r4[j], v5 = r5[j];
    auto rotate = [](double cg, double sg, double& upper, double& lower) {
      const double t1 = upper, t2 = lower;
      upper = cg * t1 + sg * t2;
      lower = -sg * t1 + cg * t2;
    };
    rotate(c[0], s[0], v0, v3);
    rotate(c[1], s[1], v0, v4);
    rotate(c[2], s[2], v0, v5);
    rotate(c[3], s[3], v1, v3);
    rotate(c[4], s[4], v1, v4);
    rotate(c[5], s[5], v1, v5);
    rotate(c[6], s[6], v2, v3);
    rotate(c[7], s[7], v2, v4);
    rotate(c[8], s[8], v2, v5);
    r0[j] = v0;
    r1[j] = v1;
    r2[j] = v2;
    r3[j] = v3;
    r4[j] = v4;
    r5[j] = v5;
  }
}

#ifdef ANCHORMAP_GIVENS_AVX512
bool UseAvx512() {
  static const bool has = [] {
    __builtin_cpu_init();
    // Exactly where the loader picks the AVX2 + FMA build, whose bits these are.
    return __builtin_cpu_supports("x86-64-v3") != 0 && __builtin_cpu_supports("avx512f") != 0;
  }();
  return has && BlockGivensAvx512Allowed().load(std::memory_order_relaxed);
}

__attribute__((target("avx512f"), always_inline)) inline void RotateAll(const __m512d* cs,
                                                                        const __m512d* sn,
                                                                        __m512d* v) {
  for (int k = 0, g = 0; k < 3; ++k) {
    for (int low = 3; low < 6; ++low, ++g) {
      const __m512d t1 = v[k], t2 = v[low];
      v[k] = _mm512_fmadd_pd(cs[g], t1, _mm512_mul_pd(sn[g], t2));
      v[low] = _mm512_fnmadd_pd(sn[g], t1, _mm512_mul_pd(cs[g], t2));
    }
  }
}

// ApplyRotations with eight columns per register, written as the AVX2 + FMA build compiles
// `cg * t1 + sg * t2` and `-sg * t1 + cg * t2`: the first product fused into the sum of
// the second. All 18 factors and the six rows fit in AVX-512's 32 registers.
__attribute__((target("avx512f"))) void ApplyRotationsAvx512(const double* c, const double* s,
                                                             double* const row[6], int n) {
  __m512d cs[9], sn[9];
  for (int g = 0; g < 9; ++g) {
    cs[g] = _mm512_set1_pd(c[g]);
    sn[g] = _mm512_set1_pd(s[g]);
  }
  int j = 0;
  for (; j + 8 <= n; j += 8) {
    __m512d v[6];
    for (int r = 0; r < 6; ++r) v[r] = _mm512_loadu_pd(row[r] + j);
    RotateAll(cs, sn, v);
    for (int r = 0; r < 6; ++r) _mm512_storeu_pd(row[r] + j, v[r]);
  }
  if (j < n) {
    const __mmask8 mask = static_cast<__mmask8>((1u << (n - j)) - 1u);
    __m512d v[6];
    for (int r = 0; r < 6; ++r) v[r] = _mm512_maskz_loadu_pd(mask, row[r] + j);
    RotateAll(cs, sn, v);
    for (int r = 0; r < 6; ++r) _mm512_mask_storeu_pd(row[r] + j, mask, v[r]);
  }
}
#endif

}  // namespace

std::atomic<bool>& BlockGivensAvx512Allowed() {
  static std::atomic<bool> allowed{true};
  return allowed;
}

ANCHORMAP_CPU_CLONES void EliminateBlockRow(double* upper, double* lower, int stride, int width) {
  double* row[6];
  for (int r = 0; r < 3; ++r) {
    row[r] = upper + r * stride;
    row[3 + r] = lower + r * stride;
  }

  // The nine rotations, in order: column k of row k against rows 3, 4, 5. Rotation
  // (c, s) = (1, 0) where the entry is already zero (leaves both rows exactly as they are).
  double c[9], s[9];
  for (int k = 0, g = 0; k < 3; ++k) {
    for (int low = 3; low < 6; ++low, ++g) {
      const double a = row[k][k], b = row[low][k];
      if (b == 0.0) {
        c[g] = 1.0;
        s[g] = 0.0;
        continue;
      }
      const double r = std::sqrt(a * a + b * b);  // entries are O(1e-6..1e6): no overflow
      c[g] = a / r;
      s[g] = b / r;
      for (int j = k; j < 3; ++j) {
        const double t1 = row[k][j], t2 = row[low][j];
        row[k][j] = c[g] * t1 + s[g] * t2;
        row[low][j] = -s[g] * t1 + c[g] * t2;
      }
      row[low][k] = 0.0;
    }
  }

#ifdef ANCHORMAP_GIVENS_AVX512
  if (UseAvx512()) {
    double* const right[6] = {row[0] + 3, row[1] + 3, row[2] + 3,
                              row[3] + 3, row[4] + 3, row[5] + 3};
    ApplyRotationsAvx512(c, s, right, width - 3);
    return;
  }
#endif
  ApplyRotations(c, s, row[0] + 3, row[1] + 3, row[2] + 3, row[3] + 3, row[4] + 3, row[5] + 3,
                 width - 3);
}

}  // namespace anchormap
