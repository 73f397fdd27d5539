#include "tools/eval/error_stats.h"

#include <algorithm>
#include <cmath>

namespace anchormap {

ErrorStats ComputeErrorStats(std::vector<double> errors) {
  ErrorStats stats;
  if (errors.empty()) return stats;
  std::sort(errors.begin(), errors.end());
  const double n = static_cast<double>(errors.size());
  double sum = 0.0, sum_sq = 0.0;
  for (double e : errors) {
    sum += e;
    sum_sq += e * e;
  }
  stats.count = static_cast<int64_t>(errors.size());
  stats.mean = sum / n;
  stats.rmse = std::sqrt(sum_sq / n);
  if (errors.size() > 1) {
    double centred = 0.0;  // two passes: no cancellation when errors are nearly equal
    for (double e : errors) centred += (e - stats.mean) * (e - stats.mean);
    stats.std = std::sqrt(centred / (n - 1.0));
  }
  const size_t mid = errors.size() / 2;
  stats.median = errors.size() % 2 ? errors[mid] : 0.5 * (errors[mid - 1] + errors[mid]);
  stats.min = errors.front();
  stats.max = errors.back();
  return stats;
}

}  // namespace anchormap
