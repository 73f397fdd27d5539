#pragma once
// One daemon's event loop: an LCM instance plus a Boost.Asio io_context (docs/ARCHITECTURE.md,
// "A keyframe's path"). LCM's file descriptor is watched as a posix::stream_descriptor (and
// released before lcm_destroy, since LCM owns it); timers run periodic work (publishing,
// status lines); SIGINT and SIGTERM stop the loop so that main() returns and everything
// is destroyed in order. One thread: handlers, timers and publishing never overlap.
//
// Handlers get raw bytes (no typed LCM subscribe, which drops undecodable messages
// silently); the caller decodes with codec.h and counts rejections. Each subscription's
// queue is raised from LCM's default of 30 messages. LCM 1.3.1 cannot report a queue's
// fill level, so the loop reports the largest number of messages it found waiting in one
// wake-up (`max_burst`), the closest observable proxy.

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <boost/asio/io_context.hpp>

#include "common/util/status.h"

namespace anchormap {

class OptionsLoader;
// The --lcm-url option, registered alike by every daemon on the bus (agent, server, viewer).
void AddLcmUrlOption(OptionsLoader* loader, std::string* lcm_url);

struct LcmLoopStats {
  int64_t messages_handled = 0;
  int64_t wakeups = 0;
  int64_t max_burst = 0;  // most messages dispatched in one wake-up
  int64_t publish_failures = 0;
  // Datagrams the kernel dropped on this process's UDP sockets (full receive buffers),
  // from /proc/net/udp and udp6, as of the last RefreshKernelDrops(); -1 when unreadable.
  // LCM 1.3.1 cannot report what its own per-subscription queues dropped.
  int64_t kernel_drops = 0;
};

// The sum of the "drops" column of /proc/net/udp{,6} over the sockets this process owns
// (matched by inode through /proc/self/fd); -1 when /proc cannot be read.
int64_t ReadOwnUdpDrops();

class LcmLoop {
 public:
  using RawHandler =
      std::function<void(const std::string& channel, const uint8_t* data, size_t size)>;

  // Opens LCM at `url` ("" = LCM's default, or $LCM_DEFAULT_URL).
  static Result<std::unique_ptr<LcmLoop>> Create(const std::string& url);
  ~LcmLoop();
  LcmLoop(const LcmLoop&) = delete;
  LcmLoop& operator=(const LcmLoop&) = delete;

  boost::asio::io_context& io();

  // Subscribes `handler` to `channel` (an LCM regular expression; plain names match
  // themselves) with a receive queue of `queue_capacity` messages.
  Status Subscribe(const std::string& channel, RawHandler handler, int queue_capacity = 1000);
  Status Publish(const std::string& channel, const std::vector<uint8_t>& bytes);

  // Calls `tick` every `period` (first call one period from now) while the loop runs.
  void Every(std::chrono::milliseconds period, std::function<void()> tick);

  // Stops the loop on SIGINT / SIGTERM; `on_signal` (optional) runs first with the number.
  void StopOnSignals(std::function<void(int)> on_signal = nullptr);
  // Gives SIGINT / SIGTERM back their default action (the process ends). For the work a
  // daemon does after its loop stopped: a second signal then ends it at once.
  void RestoreDefaultSignals();

  // Runs until Stop() or a handled signal.
  void Run();
  // Runs until `done()` is true (checked after every handler) or `timeout` passes.
  // Returns done(). For tests and bounded waits.
  bool RunUntil(const std::function<bool()>& done, std::chrono::milliseconds timeout);
  void Stop();
  // Dispatches every message already waiting (including those its handlers publish) on
  // the calling thread, up to `max_messages`; returns how many. For tests over memq://
  // and deterministic draining; never call it from inside a handler.
  int64_t HandlePending(int64_t max_messages = 1'000'000);

  const LcmLoopStats& stats() const;
  // Updates stats().kernel_drops (reads /proc: call it at status time, not per message).
  void RefreshKernelDrops();

 private:
  LcmLoop();
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace anchormap
