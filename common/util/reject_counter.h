#pragma once
// Why an input was refused, and a counter of refusals by reason. Bad input (bus
// messages, log files) is never fatal: the codec and the logic classes return a
// Status with an ErrorCode, the daemon counts it here, which logs the first refusal of each kind
// and feeds the status line and the status message.
//
// It lives in util/ rather than bus/ because the bus-free logic
// classes (agent/, server/) reject inputs for their own reasons (a reused sequence
// number, an encounter that never found its keyframes) and must count them in the same
// table without including anything from the bus.

#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "common/util/error_code.h"
#include "common/util/log.h"

namespace anchormap {

class Status;

class RejectCounter {
 public:
  // Counts one refusal; logs it (as a warning, with `context` and `detail`) the first
  // time this (reason, context) pair is seen. `context` is e.g. the channel name.
  void Count(ErrorCode reason, const std::string& context, const std::string& detail);
  // The same for a failed Status (its code and message).
  void Count(const Status& refusal, const std::string& context);

  // Adds `n` to a reason's count without logging (a restored snapshot's counts).
  void Restore(ErrorCode reason, int64_t n) { counts_[static_cast<int>(reason)] += n; }
  int64_t count(ErrorCode reason) const { return counts_[static_cast<int>(reason)]; }
  int64_t total() const;
  // Reasons with a non-zero count, in enum order: (name, count).
  std::vector<std::pair<std::string, int64_t>> NonZero() const;
  // "not_finite=3 duplicate_sequence=1", or "none".
  std::string Summary() const;

 private:
  std::array<int64_t, static_cast<int>(ErrorCode::kNumCodes)> counts_{};
  OncePerKindLog once_;
};

}  // namespace anchormap
