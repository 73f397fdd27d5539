#include "tools/replay/in_process_bus.h"

#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

std::vector<uint8_t> Bytes(const std::string& text) { return {text.begin(), text.end()}; }
std::string Text(const uint8_t* data, size_t size) { return std::string(data, data + size); }

TEST(InProcessBusTest, DeliversInPublicationOrderWithRepliesQueuedBehind) {
  InProcessBus bus;
  std::vector<std::string> seen;
  // "A" answers each message with one on "B": as with memq://, the answer waits behind
  // what was already queued.
  bus.Subscribe("A", [&](const std::string& channel, const uint8_t* data, size_t size) {
    seen.push_back(channel + ":" + Text(data, size));
    bus.Publish("B", Bytes("re-" + Text(data, size)));
  });
  bus.Subscribe("B", [&](const std::string& channel, const uint8_t* data, size_t size) {
    seen.push_back(channel + ":" + Text(data, size));
  });
  bus.Publish("A", Bytes("1"));
  bus.Publish("A", Bytes("2"));
  EXPECT_EQ(bus.HandlePending(), 4);
  EXPECT_EQ(seen, (std::vector<std::string>{"A:1", "A:2", "B:re-1", "B:re-2"}));
  EXPECT_EQ(bus.queued(), 0u);
  EXPECT_EQ(bus.HandlePending(), 0);
}

TEST(InProcessBusTest, EveryHandlerOfAChannelInSubscriptionOrderAndUnheardChannelsDropped) {
  InProcessBus bus;
  std::string order;
  bus.Subscribe("X", [&](const std::string&, const uint8_t*, size_t) { order += "first "; });
  bus.Subscribe("X", [&](const std::string&, const uint8_t* data, size_t size) {
    order += "second:" + Text(data, size);
  });
  bus.Publish("NOBODY", Bytes("lost"));
  EXPECT_EQ(bus.queued(), 0u);
  bus.Publish("X", Bytes("m"));
  bus.Publish("X", {});  // an empty message is still a message
  EXPECT_EQ(bus.HandlePending(), 2);
  EXPECT_EQ(order, "first second:mfirst second:");
}

}  // namespace
}  // namespace anchormap
