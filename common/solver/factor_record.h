#pragma once
// A factor as the smoother holds it (internal to common/solver): the factor, its variables
// by index, and whether it is still part of the graph.

#include <array>

#include "common/solver/factor.h"

namespace anchormap {
namespace smoother_internal {

struct FactorRecord {
  Factor factor;
  std::array<int, kMaxFactorKeys> vars{};
  int num_vars = 0;
  bool active = true;  // false once removed (a gauge prior dropped at a merge)
};

}  // namespace smoother_internal
}  // namespace anchormap
