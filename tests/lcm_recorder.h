#pragma once
// Records the LCM channels matching a regular expression into an LCM log (lcm-logger's
// format: every reader of ours and lcm-logplayer read it), for the system tests.
//
// Why not lcm-logger: LCM (1.3.1) queues at most 30 messages per subscription between its
// receive thread and the thread that runs the handlers, and drops the rest. A server's final
// map goes out in one burst of ~75 messages, so a logger whose handler thread lagged on a
// loaded machine recorded an older map (docs/ARCHITECTURE.md, "CI's time"). Here the queue
// is unbounded (a capacity <= 0 means no limit in lcm.c) and the socket's receive buffer is
// 4 MiB unless the URL sets recv_buf_size; on stop, what LCM already holds is still written.

#include <csignal>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <string>

#include "common/bus/lcm_log.h"
#include "common/util/status.h"

namespace anchormap {

struct RecorderCounts {
  int64_t events = 0;
  int64_t bytes = 0;  // payload bytes
  std::map<std::string, int64_t> events_per_channel;
  // Most events written back to back, each already waiting when the one before was done:
  // how far the handler fell behind the receive thread (lcm-logger would have dropped what
  // lay beyond 31 of one channel regex).
  int64_t longest_backlog = 0;
  // Datagrams the kernel dropped on the recorder's sockets (full receive buffer, any
  // channel on the bus), -1 when /proc could not be read.
  int64_t kernel_drops = 0;
};

// `url` with recv_buf_size=4194304 added unless it already names a recv_buf_size ("" is
// read as $LCM_DEFAULT_URL, or LCM's default udpm URL).
std::string WithLargeReceiveBuffer(const std::string& url);

class LcmRecorder {
 public:
  // Opens LCM at WithLargeReceiveBuffer(url), subscribes to `channels` (an LCM regular
  // expression) with an unbounded queue, and creates (truncates) `output`.
  static Result<std::unique_ptr<LcmRecorder>> Open(const std::string& url,
                                                   const std::string& channels,
                                                   const std::string& output);
  ~LcmRecorder();
  LcmRecorder(const LcmRecorder&) = delete;
  LcmRecorder& operator=(const LcmRecorder&) = delete;

  // Records until *stop is non-zero (looked at every 100 ms at the latest, and whenever a
  // signal interrupts the wait), flushing the file whenever nothing waits; then writes what
  // LCM still holds (until 50 ms pass without a message, at most 2 s) and closes the file.
  Status Run(const volatile std::sig_atomic_t* stop);

  const RecorderCounts& counts() const { return counts_; }

 private:
  LcmRecorder();
  struct Lcm;  // LCM's instance and subscription; its handler calls Write
  friend struct Lcm;
  void Write(int64_t receive_utime, const char* channel, const void* data, size_t size);
  // Waits up to `timeout_ms` for one message and writes it and every one already waiting;
  // returns how many it wrote (0: none came), or the failure.
  Result<int64_t> RecordWaiting(int timeout_ms);

  std::unique_ptr<Lcm> lcm_;
  LcmLogWriter writer_;
  Status write_status_;
  RecorderCounts counts_;
};

}  // namespace anchormap
