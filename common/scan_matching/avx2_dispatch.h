#pragma once
// Runtime dispatch to AVX2 code paths: a build for x86-64 with GCC or Clang compiles the AVX2
// functions (`__attribute__((target("avx2")))`, ANCHORMAP_AVX2_DISPATCH defined) beside the
// portable ones, and CpuHasAvx2() chooses at run time, so one binary serves every x86-64 CPU.
// Each AVX2 path gives the same results as its portable twin (their tests compare them).

#if defined(__x86_64__) && defined(__GNUC__)
#define ANCHORMAP_AVX2_DISPATCH 1
#include <immintrin.h>

namespace anchormap {

inline bool CpuHasAvx2() {
  static const bool has = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") != 0;
  }();
  return has;
}

}  // namespace anchormap
#endif
