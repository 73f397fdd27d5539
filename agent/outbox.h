#pragma once
// The agent's side of reliable delivery (docs/ARCHITECTURE.md, "A keyframe's path"), with
// no bus: every keyframe and relayed encounter the agent published, kept (as its encoded
// bytes, opaque here) until the server acknowledges it, so that it can be sent again when
// the server asks for it (a resend request naming sequence ranges) or when no
// acknowledgement came within a timeout (the last messages of a burst, whose loss the
// server cannot see).
//
// Memory is bounded (OutboxOptions::max_bytes). Past the bound the oldest entries are
// spilled to a scratch file in OutboxOptions::spill_dir (agent/spill_file.h) and read back
// from it, in order, when they are resent: nothing is lost while the agent runs, however
// long the server is away, until the spill file reaches max_spill_bytes. Only then (or
// without a spill folder, or when the file cannot be written) are the oldest entries
// dropped, counted (dropped()) and reported to the caller as a kQueueFull Status; the
// server then bridges the gap after its hold time. The clock is the caller's (wall time).

#include <cstddef>
#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "agent/spill_file.h"
#include "common/types/delivery.h"
#include "common/util/status.h"

namespace anchormap {

struct OutboxOptions {
  // Bytes kept in memory for resending at most (keyframes with scans are a few KB each;
  // 64 MiB keeps hours of a typical robot's keyframes while the server is unreachable).
  int64_t max_bytes = int64_t{64} << 20;
  // Folder of the spill file (empty: no spilling; past max_bytes the oldest are dropped).
  std::string spill_dir;
  // Bytes written to the spill file at most (it is emptied when everything in it has been
  // acknowledged); past it the oldest in memory are dropped.
  int64_t max_spill_bytes = int64_t{4} << 30;
  // An unacknowledged entry is sent again after this long without an acknowledgement or
  // a request, then after 2 and 4 times this (and 4 times this from then on).
  double resend_timeout_s = 2.0;
  // At most this many timed-out entries are resent per Poll (the server asks for the rest).
  int max_resend_per_poll = 16;
  // An acknowledgement that leaves an encounter unacknowledged this long after it was last
  // sent has it sent again at once (0: off). The server cannot see a lost encounter that
  // no later one follows (a restarted server: the ones sent while it was down), and the
  // timeout's back-off would bring it after the inputs that follow it in data time had
  // gone into the map (late: with the scan sources on, other decisions); an
  // acknowledgement shows the server is there to take it. Encounters are small; keyframes
  // are not, and the next keyframe reveals a lost one (the server asks for it).
  double encounter_resend_after_ack_s = 1.0;

  Status Validate() const {
    if (max_bytes < 1024) return Status::Error("outbox.max_bytes must be >= 1024");
    if (max_spill_bytes < 0) return Status::Error("outbox.max_spill_bytes must be >= 0");
    if (!(resend_timeout_s > 0)) return Status::Error("outbox.resend_timeout_s must be > 0");
    if (max_resend_per_poll < 1) return Status::Error("outbox.max_resend_per_poll must be >= 1");
    if (!(encounter_resend_after_ack_s >= 0)) {
      return Status::Error("outbox.encounter_resend_after_ack_s must be >= 0");
    }
    return Status::Ok();
  }
};

struct OutboxStats {
  int64_t added = 0;
  int64_t acknowledged = 0;
  int64_t resent_on_request = 0;
  int64_t resent_on_timeout = 0;
  int64_t resent_after_ack = 0;    // encounters an acknowledgement left out (see the option)
  int64_t requested_but_gone = 0;  // asked for, but acknowledged or dropped before
  int64_t spilled = 0;             // written to the spill file (past the memory bound)
  int64_t read_back = 0;           // read from the spill file to be resent
  int64_t spill_failures = 0;      // spill writes or reads that failed (logged by the caller)
  int64_t dropped = 0;             // pushed out by the bounds, never acknowledged
};

class Outbox {
 public:
  // A message to send again: its stream, sequence number and encoded bytes.
  struct Message {
    StreamKind kind = StreamKind::kKeyframes;
    int32_t seq = 0;
    std::vector<uint8_t> bytes;
  };

  explicit Outbox(const OutboxOptions& options = {}) : options_(options) {}

  // Keeps a message that has just been sent for the first time. Returns kQueueFull when
  // the bounds pushed older unacknowledged entries out (they are counted), kIoError when
  // the spill file failed (the entries it should have taken were dropped).
  Status Add(StreamKind kind, int32_t seq, std::vector<uint8_t> bytes, int64_t now_utime);
  // A cumulative acknowledgement: frees every entry below the two bounds.
  void Acknowledge(int32_t keyframes_next, int32_t encounters_next);
  // Right after Acknowledge: the encounters still unacknowledged that were last sent at
  // least encounter_resend_after_ack_s before `now_utime` (at most max_resend_per_poll,
  // oldest first), marked as sent at `now_utime`.
  std::vector<Message> EncountersLeftByAck(int64_t now_utime);
  // The kept entries in `ranges`, in stream and seq order (spilled ones read back), marked
  // as sent at `now_utime`.
  std::vector<Message> Requested(const std::vector<SeqRange>& ranges, int64_t now_utime);
  // The unacknowledged entries whose resend timeout (with back-off) has run out, oldest
  // first, at most max_resend_per_poll, marked as sent at `now_utime`.
  std::vector<Message> TimedOut(int64_t now_utime);

  size_t size() const { return keyframes_.size() + encounters_.size(); }
  // What is unacknowledged, for a log line: "keyframes 120..122 (3), encounters 4..4 (1)".
  std::string Unacknowledged() const;
  size_t bytes() const { return bytes_; }  // in memory
  size_t spilled_entries() const { return spilled_entries_; }
  int64_t spill_file_bytes() const { return spill_ ? spill_->size() : 0; }
  const OutboxStats& stats() const { return stats_; }
  // The last spill failure (Ok when none).
  const Status& spill_error() const { return spill_error_; }

 private:
  struct Entry {
    StreamKind kind = StreamKind::kKeyframes;
    int32_t seq = 0;
    std::vector<uint8_t> bytes;  // empty when spilled
    int64_t spill_offset = -1;   // >= 0: the bytes are in the spill file
    size_t size = 0;
    int64_t last_sent_utime = 0;
    int sends = 1;
    bool spilled() const { return spill_offset >= 0; }
  };
  using Stream = std::map<int32_t, Entry>;

  Stream& StreamOf(StreamKind kind) {
    return kind == StreamKind::kKeyframes ? keyframes_ : encounters_;
  }
  void Erase(Stream* stream, Stream::iterator it);
  // Moves the oldest in-memory entries out (to the spill file, or dropped) until the
  // memory bound holds; returns how many were dropped.
  int64_t EnforceMemoryBound();
  // The oldest entry of `stream` still in memory (end() when none).
  Stream::iterator OldestInMemory(Stream* stream);
  // Writes `entry` to the spill file; false when it cannot (full, no folder, I/O error).
  bool Spill(Entry* entry);
  // A copy of `entry` to send, marked as sent; false when its spilled bytes cannot be read.
  bool TakeForSending(Entry* entry, int64_t now_utime, std::vector<Message>* out);

  OutboxOptions options_;
  Stream keyframes_;
  Stream encounters_;
  size_t in_memory_[2] = {0, 0};  // entries in memory per stream (index: kind)
  size_t bytes_ = 0;              // bytes in memory
  size_t spilled_entries_ = 0;
  int32_t last_spilled_seq_[2] = {std::numeric_limits<int32_t>::min(),
                                  std::numeric_limits<int32_t>::min()};  // per stream
  std::unique_ptr<SpillFile> spill_;
  Status spill_error_;
  OutboxStats stats_;
};

}  // namespace anchormap
