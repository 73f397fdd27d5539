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
  std::vector<int> start(1, 0), variables;
  for (const std::vector<int>& vars : factor_variables) {
    variables.insert(variables.end(), vars.begin(), vars.end());
    start.push_back(static_cast<int>(variables.size()));
  }
  return ComputeOrdering(num_variables, start, variables, keep_last);
}

Result<std::vector<int>> ComputeOrdering(int num_variables, const std::vector<int>& factor_start,
                                         const std::vector<int>& variables,
                                         const std::vector<bool>& keep_last) {
  if (orderings_to_fail > 0) {
    --orderings_to_fail;
    return Status::Error(ErrorCode::kNumericalFailure, "ccolamd failed (injected by a test)");
  }
  std::vector<int> order(num_variables);
  std::iota(order.begin(), order.end(), 0);
  if (num_variables <= 1) return order;

  // CCOLAMD wants the factor x variable pattern in compressed-column form: count, then
  // fill in factor order (so each column's rows come sorted), then drop repeats (a
  // variable listed twice by one factor).
  const int num_rows = static_cast<int>(factor_start.size()) - 1;
  std::vector<int> p(num_variables + 1, 0);
  for (int v : variables) ++p[v + 1];
  for (int v = 0; v < num_variables; ++v) p[v + 1] += p[v];
  const int listed = p[num_variables];
  const size_t alen = ccolamd_recommended(listed, num_rows, num_variables);
  std::vector<int> A(std::max<size_t>(alen, static_cast<size_t>(listed)));
  {
    std::vector<int> next(p.begin(), p.end() - 1);
    for (int f = 0; f < num_rows; ++f) {
      for (int k = factor_start[f]; k < factor_start[f + 1]; ++k) A[next[variables[k]]++] = f;
    }
  }
  int nnz = 0;
  for (int v = 0; v < num_variables; ++v) {
    const int first = p[v], last = p[v + 1];
    p[v] = nnz;
    for (int k = first; k < last; ++k) {
      if (k == first || A[k] != A[k - 1]) A[nnz++] = A[k];
    }
  }
  p[num_variables] = nnz;
  std::vector<int> constraint(num_variables);
  for (int v = 0; v < num_variables; ++v) constraint[v] = keep_last[v] ? 1 : 0;

  double knobs[CCOLAMD_KNOBS];
  int stats[CCOLAMD_STATS];
  ccolamd_set_defaults(knobs);
  if (!ccolamd(num_rows, num_variables, static_cast<int>(A.size()), A.data(), p.data(), knobs,
               stats, constraint.data())) {
    return Status::Error(ErrorCode::kNumericalFailure,
                         "ccolamd failed with status " + std::to_string(stats[CCOLAMD_STATUS]));
  }
  std::copy(p.begin(), p.begin() + num_variables, order.begin());
  return order;
}

}  // namespace anchormap
