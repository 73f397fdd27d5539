#include "common/bus/lcm_loop.h"

#include <csignal>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

TEST(LcmLoopTest, DeliversRawBytesOverMemq) {
  Result<std::unique_ptr<LcmLoop>> created = LcmLoop::Create("memq://");
  ASSERT_TRUE(created.ok()) << created.status().message();
  std::unique_ptr<LcmLoop> loop = std::move(*created);
  std::vector<std::string> received;
  ASSERT_TRUE(loop->Subscribe("R1_.*",
                              [&](const std::string& channel, const uint8_t* data, size_t size) {
                                received.push_back(
                                    channel + ":" +
                                    std::string(reinterpret_cast<const char*>(data), size));
                              })
                  .ok());
  ASSERT_TRUE(loop->Publish("R1_LASER", {'a', 'b'}).ok());
  ASSERT_TRUE(loop->Publish("R2_LASER", {'x'}).ok());  // not subscribed
  ASSERT_TRUE(loop->Publish("R1_ODOMETRY", {'c'}).ok());
  EXPECT_TRUE(loop->RunUntil([&] { return received.size() == 2; }, std::chrono::seconds(5)));
  ASSERT_EQ(received.size(), 2u);
  EXPECT_EQ(received[0], "R1_LASER:ab");
  EXPECT_EQ(received[1], "R1_ODOMETRY:c");
  EXPECT_GE(loop->stats().messages_handled, 2);
  EXPECT_GE(loop->stats().max_burst, 1);
}

TEST(LcmLoopTest, QueueCapacityAboveLcmDefaultKeepsABurstOf500) {
  Result<std::unique_ptr<LcmLoop>> created = LcmLoop::Create("memq://");
  ASSERT_TRUE(created.ok()) << created.status().message();
  std::unique_ptr<LcmLoop> loop = std::move(*created);
  int count = 0;
  ASSERT_TRUE(loop->Subscribe(
                      "BURST", [&](const std::string&, const uint8_t*, size_t) { ++count; }, 1000)
                  .ok());
  for (int i = 0; i < 500; ++i) ASSERT_TRUE(loop->Publish("BURST", {1, 2, 3}).ok());
  EXPECT_TRUE(loop->RunUntil([&] { return count == 500; }, std::chrono::seconds(5)));
  EXPECT_EQ(count, 500);  // LCM's default capacity of 30 would keep 30 of them
}

TEST(LcmLoopTest, TimersTickAndStopEndsRun) {
  Result<std::unique_ptr<LcmLoop>> created = LcmLoop::Create("memq://");
  ASSERT_TRUE(created.ok()) << created.status().message();
  std::unique_ptr<LcmLoop> loop = std::move(*created);
  int ticks = 0;
  loop->Every(std::chrono::milliseconds(5), [&] {
    if (++ticks == 3) loop->Stop();
  });
  loop->Run();  // returns only through Stop()
  EXPECT_EQ(ticks, 3);
}

TEST(LcmLoopTest, SigtermStopsTheLoopCleanly) {
  Result<std::unique_ptr<LcmLoop>> created = LcmLoop::Create("memq://");
  ASSERT_TRUE(created.ok()) << created.status().message();
  std::unique_ptr<LcmLoop> loop = std::move(*created);
  int signal_seen = 0;
  loop->StopOnSignals([&](int number) { signal_seen = number; });
  loop->Every(std::chrono::milliseconds(10), [] { std::raise(SIGTERM); });
  loop->Run();
  EXPECT_EQ(signal_seen, SIGTERM);
}

TEST(LcmLoopDeathTest, ASignalAfterRestoringTheDefaultsEndsTheProcess) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(
      {
        Result<std::unique_ptr<LcmLoop>> created = LcmLoop::Create("memq://");
        if (!created.ok()) std::exit(3);
        std::unique_ptr<LcmLoop> loop = std::move(*created);
        loop->StopOnSignals();
        loop->Every(std::chrono::milliseconds(10), [] { std::raise(SIGTERM); });
        loop->Run();  // the first SIGTERM stops the loop only
        loop->RestoreDefaultSignals();
        std::raise(SIGTERM);
        std::exit(0);  // not reached
      },
      ::testing::KilledBySignal(SIGTERM), "");
}

TEST(LcmLoopTest, HandlerExceptionsAreContained) {
  Result<std::unique_ptr<LcmLoop>> created = LcmLoop::Create("memq://");
  ASSERT_TRUE(created.ok()) << created.status().message();
  std::unique_ptr<LcmLoop> loop = std::move(*created);
  int calls = 0;
  ASSERT_TRUE(loop->Subscribe("X",
                              [&](const std::string&, const uint8_t*, size_t) {
                                if (++calls == 1) throw std::runtime_error("boom");
                              })
                  .ok());
  ASSERT_TRUE(loop->Publish("X", {1}).ok());
  ASSERT_TRUE(loop->Publish("X", {2}).ok());
  EXPECT_TRUE(loop->RunUntil([&] { return calls == 2; }, std::chrono::seconds(5)));
}

TEST(LcmLoopTest, HandlePendingDrainsChainsOfMessages) {
  Result<std::unique_ptr<LcmLoop>> created = LcmLoop::Create("memq://");
  ASSERT_TRUE(created.ok()) << created.status().message();
  std::unique_ptr<LcmLoop> loop = std::move(*created);
  int pings = 0, pongs = 0;
  ASSERT_TRUE(loop->Subscribe("PING",
                              [&](const std::string&, const uint8_t*, size_t) {
                                ++pings;
                                ASSERT_TRUE(loop->Publish("PONG", {1}).ok());
                              })
                  .ok());
  ASSERT_TRUE(
      loop->Subscribe("PONG", [&](const std::string&, const uint8_t*, size_t) { ++pongs; }).ok());
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(loop->Publish("PING", {0}).ok());
  EXPECT_EQ(loop->HandlePending(), 6);
  EXPECT_EQ(pings, 3);
  EXPECT_EQ(pongs, 3);
  EXPECT_EQ(loop->HandlePending(), 0);
}

TEST(LcmLoopTest, BadUrlIsAnErrorNotACrash) {
  const Result<std::unique_ptr<LcmLoop>> loop = LcmLoop::Create("nosuchprovider://");
  ASSERT_FALSE(loop.ok());
  EXPECT_EQ(loop.status().code(), ErrorCode::kIoError);
  EXPECT_NE(loop.status().message().find("nosuchprovider://"), std::string::npos);
}

}  // namespace
}  // namespace anchormap
