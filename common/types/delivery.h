#pragma once
// Reliable delivery of keyframes and relayed encounters (docs/ARCHITECTURE.md, "A
// keyframe's path"): the server acknowledges what it holds and asks for what it misses;
// the agent keeps what it sent until acknowledged and resends on request. Plain values
// (anchormap.delivery_ack_t and anchormap.resend_request_t on the bus; the codec converts).

#include <cstdint>
#include <string>
#include <vector>

namespace anchormap {

// What a sequence number counts: each trajectory has one sequence of keyframes and one of
// relayed encounters.
enum class StreamKind : int8_t { kKeyframes = 0, kEncounters = 1 };

// Cumulative acknowledgement of one trajectory: every keyframe with seq < keyframes_next
// and every encounter with seq < encounters_next is in the server's hands.
struct DeliveryAck {
  int64_t utime = 0;
  std::string robot;
  int64_t trajectory_id = 0;
  int32_t keyframes_next = 0;
  int32_t encounters_next = 0;
};

// Inclusive range of missing sequence numbers of one stream.
struct SeqRange {
  StreamKind kind = StreamKind::kKeyframes;
  int32_t first = 0;
  int32_t last = 0;
  bool operator==(const SeqRange& o) const {
    return kind == o.kind && first == o.first && last == o.last;
  }
};

// The server asks one trajectory's agent for these ranges again.
struct ResendRequest {
  int64_t utime = 0;
  std::string robot;
  int64_t trajectory_id = 0;
  std::vector<SeqRange> ranges;
};

}  // namespace anchormap
