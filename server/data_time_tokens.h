#pragma once
// The token bucket of the sources' budgets (GlobalSearchQueue, MatchBudget), refilled in
// data time: the same input accrues the same tokens, so offline replays stay deterministic.

#include <algorithm>
#include <cstdint>
#include <optional>

namespace anchormap {

// Data time advanced to now_utime (never goes back): `tokens` accrue at per_s over the time
// since `last_utime`, saving at most burst. The first call only starts the clock.
inline void RefillTokens(int64_t now_utime, double per_s, double burst, double* tokens,
                         std::optional<int64_t>* last_utime) {
  if (*last_utime && now_utime > **last_utime) {
    const double elapsed_s = 1e-6 * static_cast<double>(now_utime - **last_utime);
    *tokens = std::min(burst, *tokens + elapsed_s * per_s);
  }
  if (!*last_utime || now_utime > **last_utime) *last_utime = now_utime;
}

}  // namespace anchormap
