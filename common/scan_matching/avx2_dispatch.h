#pragma once
// Runtime dispatch to AVX2 code paths: a build for x86-64 with GCC or Clang compiles the AVX2
// functions (`__attribute__((target("avx2")))`, ANCHORMAP_AVX2_DISPATCH defined) beside the
// portable ones, and CpuHasAvx2() chooses at run time, so one binary serves every x86-64 CPU.
// Each AVX2 path gives the same results as its portable twin (their tests compare them).
// A few paths also have an AVX-512 (F and VL) form, chosen by CpuHasAvx512(), where eight lanes
// and single-operation masked stores were measured faster; the same results again.

#if defined(__x86_64__) && defined(__GNUC__)
#define ANCHORMAP_AVX2_DISPATCH 1
#include <immintrin.h>

#include <atomic>

namespace anchormap {

inline bool CpuHasAvx2() {
  static const bool has = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") != 0;
  }();
  return has;
}

// Tests turn the AVX-512 paths off to run their AVX2 twins on a CPU that has both.
inline std::atomic<bool>& Avx512Allowed() {
  static std::atomic<bool> allowed{true};
  return allowed;
}

inline bool CpuHasAvx512() {
  static const bool has = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx512f") != 0 && __builtin_cpu_supports("avx512vl") != 0;
  }();
  return has && Avx512Allowed().load(std::memory_order_relaxed);
}

}  // namespace anchormap
#endif
