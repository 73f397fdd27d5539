#include "common/util/reject_counter.h"

#include "common/util/status.h"

namespace anchormap {

const char* ToString(ErrorCode code) {
  switch (code) {
    case ErrorCode::kDecodeFailed:
      return "decode_failed";
    case ErrorCode::kNotFinite:
      return "not_finite";
    case ErrorCode::kAbsurdSize:
      return "absurd_size";
    case ErrorCode::kInvalidValue:
      return "invalid_value";
    case ErrorCode::kCovarianceNotSpd:
      return "covariance_not_spd";
    case ErrorCode::kEmptyRobotName:
      return "empty_robot_name";
    case ErrorCode::kBadSequence:
      return "bad_sequence";
    case ErrorCode::kDuplicateSequence:
      return "duplicate_sequence";
    case ErrorCode::kOutOfOrder:
      return "out_of_order";
    case ErrorCode::kNoOdometry:
      return "no_odometry";
    case ErrorCode::kWrongRobot:
      return "wrong_robot";
    case ErrorCode::kSelfEncounter:
      return "self_encounter";
    case ErrorCode::kUnknownRobot:
      return "unknown_robot";
    case ErrorCode::kEncounterTimeout:
      return "encounter_timeout";
    case ErrorCode::kNoKeyframeNearTime:
      return "no_keyframe_near_time";
    case ErrorCode::kQueueFull:
      return "queue_full";
    case ErrorCode::kSolverRejected:
      return "solver_rejected";
    case ErrorCode::kLateSequence:
      return "late_sequence";
    case ErrorCode::kUnsigned:
      return "unsigned";
    case ErrorCode::kUnknownKey:
      return "unknown_key";
    case ErrorCode::kBadTag:
      return "bad_tag";
    case ErrorCode::kReplay:
      return "replay";
    case ErrorCode::kFromFuture:
      return "from_future";
    case ErrorCode::kCapReached:
      return "cap_reached";
    case ErrorCode::kInvalidArgument:
      return "invalid_argument";
    case ErrorCode::kIoError:
      return "io_error";
    case ErrorCode::kNumericalFailure:
      return "numerical_failure";
    case ErrorCode::kNumCodes:
      break;
  }
  return "unknown_code";
}

std::string Status::ToString() const {
  if (ok()) return "ok";
  return std::string(anchormap::ToString(code_)) + ": " + message_;
}

void RejectCounter::Count(ErrorCode reason, const std::string& context, const std::string& detail) {
  const int index = static_cast<int>(reason);
  if (index < 0 || index >= static_cast<int>(ErrorCode::kNumCodes)) return;
  ++counts_[index];
  const std::string kind = std::string(ToString(reason)) + "@" + context;
  once_.Log(LogLevel::kWarning, kind,
            "rejected input on " + context + ": " + ToString(reason) + ": " + detail);
}

void RejectCounter::Count(const Status& refusal, const std::string& context) {
  Count(refusal.code(), context, refusal.message());
}

int64_t RejectCounter::total() const {
  int64_t sum = 0;
  for (int64_t c : counts_) sum += c;
  return sum;
}

std::vector<std::pair<std::string, int64_t>> RejectCounter::NonZero() const {
  std::vector<std::pair<std::string, int64_t>> out;
  for (int i = 0; i < static_cast<int>(ErrorCode::kNumCodes); ++i) {
    if (counts_[i] > 0) out.emplace_back(ToString(static_cast<ErrorCode>(i)), counts_[i]);
  }
  return out;
}

std::string RejectCounter::Summary() const {
  std::string text;
  for (const auto& [name, count] : NonZero()) {
    if (!text.empty()) text += ' ';
    text += name + "=" + std::to_string(count);
  }
  return text.empty() ? "none" : text;
}

}  // namespace anchormap
