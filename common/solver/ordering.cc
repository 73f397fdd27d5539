#include "common/solver/ordering.h"

#include <algorithm>
#include <numeric>
#include <string>

#include <ccolamd.h>

namespace anchormap {
namespace {

int orderings_to_fail = 0;  // FailNextOrderingsForTesting

}  // namespace

void FailNextOrderingsForTesting(int count) { orderings_to_fail = count; }

Result<std::vector<int>> ComputeOrdering(int num_variables,
                                         const std::vector<std::vector<int>>& factor_variables,
                                         const std::vector<bool>& keep_last) {
  if (orderings_to_fail > 0) {
    --orderings_to_fail;
    return Status::Error(ErrorCode::kNumericalFailure, "ccolamd failed (injected by a test)");
  }
  std::vector<int> order(num_variables);
  std::iota(order.begin(), order.end(), 0);
  if (num_variables <= 1) return order;

  // CCOLAMD wants the factor x variable pattern in compressed-column form.
  const int num_rows = static_cast<int>(factor_variables.size());
  std::vector<std::vector<int>> rows_of_column(num_variables);
  int nnz = 0;
  for (int f = 0; f < num_rows; ++f) {
    for (int v : factor_variables[f]) {
      rows_of_column[v].push_back(f);
      ++nnz;
    }
  }
  const size_t alen = ccolamd_recommended(nnz, num_rows, num_variables);
  std::vector<int> A(alen);
  std::vector<int> p(num_variables + 1, 0);
  for (int v = 0, k = 0; v < num_variables; ++v) {
    std::sort(rows_of_column[v].begin(), rows_of_column[v].end());
    rows_of_column[v].erase(std::unique(rows_of_column[v].begin(), rows_of_column[v].end()),
                            rows_of_column[v].end());
    for (int f : rows_of_column[v]) A[k++] = f;
    p[v + 1] = k;
  }
  std::vector<int> constraint(num_variables);
  for (int v = 0; v < num_variables; ++v) constraint[v] = keep_last[v] ? 1 : 0;

  double knobs[CCOLAMD_KNOBS];
  int stats[CCOLAMD_STATS];
  ccolamd_set_defaults(knobs);
  if (!ccolamd(num_rows, num_variables, static_cast<int>(alen), A.data(), p.data(), knobs, stats,
               constraint.data())) {
    return Status::Error(ErrorCode::kNumericalFailure,
                         "ccolamd failed with status " + std::to_string(stats[CCOLAMD_STATUS]));
  }
  std::copy(p.begin(), p.begin() + num_variables, order.begin());
  return order;
}

}  // namespace anchormap
