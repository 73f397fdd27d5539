#pragma once
// Process-wide allocator setting for programs that run the solver.
//
// A batch step allocates and frees tens of megabytes (CHOLMOD's matrices and factor, the
// normal equations, R's rows), a little more each time as the graph grows. glibc hands
// such blocks back to the kernel (mmap'd chunks, heap trimming) and the next batch step
// page-faults them in again, zero-filled: a city10000 incremental run at threshold 0.01
// (anchormap-bench-solver) takes 6.79 s without this and 5.45 s with it (whole process,
// medians of 4 A/B pairs). Keeping freed memory in the process costs nothing at the
// peak (91 MB either way) and is what a long-running server wants. Call once at the
// start of main(); a no-op without glibc.

namespace anchormap {

void RetainFreedMemory();

}  // namespace anchormap
