#pragma once
// Summary statistics of a list of non-negative errors (metres or radians), as the SLAM
// benchmarks report them: count, mean, sample standard deviation, RMSE, median, min, max.

#include <cstdint>
#include <vector>

namespace anchormap {

struct ErrorStats {
  int64_t count = 0;
  double mean = 0.0;
  double std = 0.0;  // sample standard deviation (n - 1 in the denominator); 0 when count < 2
  double rmse = 0.0;
  double median = 0.0;
  double min = 0.0;
  double max = 0.0;
};

// Statistics of `errors` (all zeros when empty). Costs O(n log n) for the median.
ErrorStats ComputeErrorStats(std::vector<double> errors);

}  // namespace anchormap
