#include "tools/replay/in_process_bus.h"

namespace anchormap {

void InProcessBus::Subscribe(const std::string& channel, Handler handler) {
  handlers_[channel].push_back(std::move(handler));
}

void InProcessBus::Publish(const std::string& channel, std::vector<uint8_t> bytes) {
  if (handlers_.count(channel) == 0) return;
  queue_.emplace_back(channel, std::move(bytes));
}

int64_t InProcessBus::HandlePending() {
  int64_t delivered = 0;
  while (!queue_.empty()) {
    // Moved out first: a handler may publish, which may grow the queue under us.
    const std::pair<std::string, std::vector<uint8_t>> message = std::move(queue_.front());
    queue_.pop_front();
    const auto it = handlers_.find(message.first);
    for (const Handler& handler : it->second) {
      handler(message.first, message.second.data(), message.second.size());
    }
    ++delivered;
  }
  return delivered;
}

}  // namespace anchormap
