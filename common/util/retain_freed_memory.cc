#include "common/util/retain_freed_memory.h"

#include <cstdlib>  // defines __GLIBC__ (through features.h) when the C library is glibc

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace anchormap {

void RetainFreedMemory() {
#if defined(__GLIBC__)
  // Serve blocks up to 1 GiB from the heap instead of fresh mmap'd pages, and never trim
  // the heap's top while less than 2 GiB of it is free.
  mallopt(M_MMAP_THRESHOLD, 1 << 30);
  mallopt(M_TRIM_THRESHOLD, static_cast<int>(0x7fffffff));
#endif
}

}  // namespace anchormap
