#pragma once
// Why an input was refused, and a counter of refusals by reason. Bad input (bus
// messages, log files) is never fatal: the codec and the logic classes return a
// RejectReason, the daemon counts it here, which logs the first refusal of each kind
// and feeds the status line and the status message.
//
// It lives in util/ rather than bus/ (LAYOUT.md's proposal) because the bus-free logic
// classes (agent/, server/) reject inputs for their own reasons (a reused sequence
// number, an encounter that never found its keyframes) and must count them in the same
// table without including anything from the bus.

#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "common/util/log.h"

namespace anchormap {

enum class RejectReason {
  kDecodeFailed = 0,    // bytes that do not decode as the channel's type
  kNotFinite,           // NaN or infinity in a number
  kAbsurdSize,          // an array length or string beyond sane limits
  kInvalidValue,        // a finite but impossible value (radstep 0, bad quaternion ...)
  kCovarianceNotSpd,    // a covariance that is not symmetric positive definite
  kEmptyRobotName,      // missing robot name
  kBadSequence,         // negative sequence number
  kDuplicateSequence,   // a sequence number seen before in the same trajectory
  kOutOfOrder,          // a time stamp older than the previous one of the stream
  kNoOdometry,          // a scan whose time the odometry does not cover
  kWrongRobot,          // a message for another robot on this robot's channel
  kSelfEncounter,       // an encounter of a robot with itself
  kUnknownRobot,        // an encounter naming a robot never seen (after waiting)
  kEncounterTimeout,    // an encounter whose keyframes did not arrive in time
  kNoKeyframeNearTime,  // an encounter too far in time from any keyframe
  kQueueFull,           // a bounded buffer overflowed, the oldest entry was dropped
  kSolverRejected,      // the smoother refused a measurement
  kNumReasons,
};

// A short stable name, e.g. "not_finite" (used in logs and server_status_t).
const char* ToString(RejectReason reason);

class RejectCounter {
 public:
  // Counts one refusal; logs it (as a warning, with `context` and `detail`) the first
  // time this (reason, context) pair is seen. `context` is e.g. the channel name.
  void Count(RejectReason reason, const std::string& context, const std::string& detail);

  int64_t count(RejectReason reason) const { return counts_[static_cast<int>(reason)]; }
  int64_t total() const;
  // Reasons with a non-zero count, in enum order: (name, count).
  std::vector<std::pair<std::string, int64_t>> NonZero() const;
  // "not_finite=3 duplicate_sequence=1", or "none".
  std::string Summary() const;

 private:
  std::array<int64_t, static_cast<int>(RejectReason::kNumReasons)> counts_{};
  OncePerKindLog once_;
};

}  // namespace anchormap
