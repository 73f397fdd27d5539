#pragma once
// What an encounter link of the merged map is, so that users and the renderer can tell the
// evidence apart (issue 11): one robot reported seeing another, a scan matched a scan of
// another trajectory, or a scan matched an earlier place of its own trajectory. The values
// are the wire's (anchormap.encounter_link_t.kind); new kinds go at the end.

#include <cstdint>

namespace anchormap {

enum class ConstraintKind : int8_t {
  kDirectEncounter = 0,
  kScanEncounter = 1,
  kLoopClosure = 2,
};

inline constexpr int8_t kNumConstraintKinds = 3;

inline bool IsValidConstraintKind(int value) { return value >= 0 && value < kNumConstraintKinds; }

// "direct", "scan", "loop" (logs, statistics).
inline const char* ToString(ConstraintKind kind) {
  switch (kind) {
    case ConstraintKind::kDirectEncounter:
      return "direct";
    case ConstraintKind::kScanEncounter:
      return "scan";
    case ConstraintKind::kLoopClosure:
      return "loop";
  }
  return "unknown";
}

}  // namespace anchormap
