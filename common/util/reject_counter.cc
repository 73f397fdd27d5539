#include "common/util/reject_counter.h"

namespace anchormap {

const char* ToString(RejectReason reason) {
  switch (reason) {
    case RejectReason::kDecodeFailed:
      return "decode_failed";
    case RejectReason::kNotFinite:
      return "not_finite";
    case RejectReason::kAbsurdSize:
      return "absurd_size";
    case RejectReason::kInvalidValue:
      return "invalid_value";
    case RejectReason::kCovarianceNotSpd:
      return "covariance_not_spd";
    case RejectReason::kEmptyRobotName:
      return "empty_robot_name";
    case RejectReason::kBadSequence:
      return "bad_sequence";
    case RejectReason::kDuplicateSequence:
      return "duplicate_sequence";
    case RejectReason::kOutOfOrder:
      return "out_of_order";
    case RejectReason::kNoOdometry:
      return "no_odometry";
    case RejectReason::kWrongRobot:
      return "wrong_robot";
    case RejectReason::kSelfEncounter:
      return "self_encounter";
    case RejectReason::kUnknownRobot:
      return "unknown_robot";
    case RejectReason::kEncounterTimeout:
      return "encounter_timeout";
    case RejectReason::kNoKeyframeNearTime:
      return "no_keyframe_near_time";
    case RejectReason::kQueueFull:
      return "queue_full";
    case RejectReason::kSolverRejected:
      return "solver_rejected";
    case RejectReason::kNumReasons:
      break;
  }
  return "unknown_reason";
}

void RejectCounter::Count(RejectReason reason, const std::string& context,
                          const std::string& detail) {
  const int index = static_cast<int>(reason);
  if (index < 0 || index >= static_cast<int>(RejectReason::kNumReasons)) return;
  ++counts_[index];
  const std::string kind = std::string(ToString(reason)) + "@" + context;
  once_.Log(LogLevel::kWarning, kind,
            "rejected input on " + context + ": " + ToString(reason) + ": " + detail);
}

int64_t RejectCounter::total() const {
  int64_t sum = 0;
  for (int64_t c : counts_) sum += c;
  return sum;
}

std::vector<std::pair<std::string, int64_t>> RejectCounter::NonZero() const {
  std::vector<std::pair<std::string, int64_t>> out;
  for (int i = 0; i < static_cast<int>(RejectReason::kNumReasons); ++i) {
    if (counts_[i] > 0) out.emplace_back(ToString(static_cast<RejectReason>(i)), counts_[i]);
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
