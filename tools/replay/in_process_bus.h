#pragma once
// The replay's bus: the agents and the server in one process hand each other their messages'
// bytes through one first-in, first-out queue, in the order LCM's memq:// delivers them (a
// message published while another is handled waits behind the ones already queued), without
// memq's pipe: memq writes, selects and reads a pipe per message, which cost ~7 % of a
// 100-robot replay's CPU in system calls (docs/ARCHITECTURE.md, anchormap-replay). Every byte
// still goes through the nodes' codecs, as on a real bus. Single-threaded; exact channel
// names only (the replay subscribes no patterns).

#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

namespace anchormap {

class InProcessBus {
 public:
  using Handler = std::function<void(const std::string& channel, const uint8_t* data, size_t size)>;

  // `handler` receives every message published on `channel` (handlers of one channel in the
  // order they subscribed).
  void Subscribe(const std::string& channel, Handler handler);
  // Queues the message; a channel nobody subscribed to is dropped, as on the bus.
  void Publish(const std::string& channel, std::vector<uint8_t> bytes);
  // Delivers queued messages, oldest first, those their handlers publish included, until the
  // queue is empty; returns how many were delivered.
  int64_t HandlePending();

  size_t queued() const { return queue_.size(); }

 private:
  std::unordered_map<std::string, std::vector<Handler>> handlers_;
  std::deque<std::pair<std::string, std::vector<uint8_t>>> queue_;
};

}  // namespace anchormap
