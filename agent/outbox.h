#pragma once
// The agent's side of reliable delivery (docs/ARCHITECTURE.md, "A keyframe's path"), with
// no bus: every keyframe and relayed encounter the agent published, kept (as its encoded
// bytes, opaque here) until the server acknowledges it, so that it can be sent again when
// the server asks for it (a resend request naming sequence ranges) or when no
// acknowledgement came within a timeout (the last messages of a burst, whose loss the
// server cannot see).
//
// Memory is bounded (OutboxOptions::max_bytes): past the bound the oldest entries are
// dropped, counted (dropped()) and reported to the caller as a kQueueFull Status; the
// server then bridges the gap after its hold time. The clock is the caller's (wall time).

#include <cstddef>
#include <cstdint>
#include <map>
#include <vector>

#include "common/types/delivery.h"
#include "common/util/status.h"

namespace anchormap {

struct OutboxOptions {
  // Bytes kept for resending at most (keyframes with scans are a few KB each; 64 MiB keeps
  // hours of a typical robot's keyframes while the server is unreachable).
  int64_t max_bytes = int64_t{64} << 20;
  // An unacknowledged entry is sent again after this long without an acknowledgement or
  // a request, then after 2 and 4 times this (and 4 times this from then on).
  double resend_timeout_s = 2.0;
  // At most this many timed-out entries are resent per Poll (the server asks for the rest).
  int max_resend_per_poll = 16;

  Status Validate() const {
    if (max_bytes < 1024) return Status::Error("outbox.max_bytes must be >= 1024");
    if (!(resend_timeout_s > 0)) return Status::Error("outbox.resend_timeout_s must be > 0");
    if (max_resend_per_poll < 1) return Status::Error("outbox.max_resend_per_poll must be >= 1");
    return Status::Ok();
  }
};

struct OutboxStats {
  int64_t added = 0;
  int64_t acknowledged = 0;
  int64_t resent_on_request = 0;
  int64_t resent_on_timeout = 0;
  int64_t requested_but_gone = 0;  // asked for, but acknowledged or dropped before
  int64_t dropped = 0;             // pushed out by the memory bound, never acknowledged
};

class Outbox {
 public:
  struct Entry {
    StreamKind kind = StreamKind::kKeyframes;
    int32_t seq = 0;
    std::vector<uint8_t> bytes;
    int64_t last_sent_utime = 0;
    int sends = 1;
  };

  explicit Outbox(const OutboxOptions& options = {}) : options_(options) {}

  // Keeps a message that has just been sent for the first time. Returns kQueueFull when
  // the memory bound pushed older unacknowledged entries out (they are counted).
  Status Add(StreamKind kind, int32_t seq, std::vector<uint8_t> bytes, int64_t now_utime);
  // A cumulative acknowledgement: frees every entry below the two bounds.
  void Acknowledge(int32_t keyframes_next, int32_t encounters_next);
  // The kept entries in `ranges`, in stream and seq order, marked as sent at `now_utime`.
  std::vector<const Entry*> Requested(const std::vector<SeqRange>& ranges, int64_t now_utime);
  // The unacknowledged entries whose resend timeout (with back-off) has run out, oldest
  // first, at most max_resend_per_poll, marked as sent at `now_utime`.
  std::vector<const Entry*> TimedOut(int64_t now_utime);

  size_t size() const { return keyframes_.size() + encounters_.size(); }
  size_t bytes() const { return bytes_; }
  const OutboxStats& stats() const { return stats_; }

 private:
  std::map<int32_t, Entry>& Stream(StreamKind kind) {
    return kind == StreamKind::kKeyframes ? keyframes_ : encounters_;
  }
  void Erase(std::map<int32_t, Entry>* stream, std::map<int32_t, Entry>::iterator it);

  OutboxOptions options_;
  std::map<int32_t, Entry> keyframes_;
  std::map<int32_t, Entry> encounters_;
  size_t bytes_ = 0;
  OutboxStats stats_;
};

}  // namespace anchormap
