#pragma once
// Why something failed: the code every Status carries (common/util/status.h). Input
// refusals are counted by code (RejectCounter), so each code has a short stable name
// that logs and server_status_t use.

namespace anchormap {

enum class ErrorCode {
  // Inputs refused (messages, log files, measurements).
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
  kLateSequence,        // a sequence number arriving after its gap was bridged (not a duplicate)
  kUnsigned,            // a message without an authenticated envelope where one is required
  kUnknownKey,          // an envelope naming a key id the receiver does not hold
  kBadTag,              // an envelope whose HMAC tag does not match (forged or corrupted)
  kReplay,              // an envelope whose counter was seen before (or is too old)
  kFromFuture,          // a data time ahead of the receiver's clock by more than allowed
  kCapReached,          // a new robot, trajectory or sender past a configured cap
  // Failures of a call or an environment.
  kInvalidArgument,   // a bad option, flag or call argument
  kIoError,           // a file that cannot be opened, read or written
  kNumericalFailure,  // a factorisation or ordering that failed (e.g. an unconstrained variable)
  kNumCodes,
};

// A short stable name, e.g. "not_finite" (used in logs and server_status_t).
const char* ToString(ErrorCode code);

}  // namespace anchormap
