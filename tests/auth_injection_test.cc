// Injection test (issue 13): a server with a key file accepts nothing from a publisher
// without the key, and refuses and counts replayed, forged, re-channelled and tampered
// envelopes; beyond authentication it refuses data from the future and robots,
// trajectories and scans past their caps. Through a memq:// bus, as the daemons are wired.
#include <gtest/gtest.h>

#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "common/bus/authenticator.h"
#include "common/bus/codec.h"
#include "common/bus/lcm_loop.h"
#include "common/util/log.h"
#include "server/node/server_node.h"
#include "tests/testing/straight_keyframes.h"

namespace anchormap {
namespace {

constexpr int64_t kNow = 1'750'000'000'000'000;  // the server's receive clock
const std::string kKeys = "fleet " + std::string(64, '1') + "\n";

Authenticator MakeAuth(const std::string& keys, const std::string& sender, int64_t first) {
  Result<KeyRing> ring = ParseKeyRing(keys);
  EXPECT_TRUE(ring.ok());
  AuthenticatorOptions options;
  options.sender = sender;
  options.first_counter = first;
  Result<Authenticator> auth = Authenticator::Create(std::move(*ring), options);
  EXPECT_TRUE(auth.ok()) << auth.status().ToString();
  return std::move(*auth);
}

Keyframe MakeKeyframe(const std::string& robot, int64_t trajectory, int32_t seq) {
  return testing::StraightKeyframe(robot, trajectory, seq, /*num_rays=*/21,
                                   /*first_utime=*/kNow - 100'000'000);
}

class AuthInjectionTest : public ::testing::Test {
 protected:
  void SetUp() override {
    SetMinLogLevel(LogLevel::kError);
    Result<std::unique_ptr<LcmLoop>> created = LcmLoop::Create("memq://");
    ASSERT_TRUE(created.ok()) << created.status().message();
    loop_ = std::move(*created);
    ServerOptions options;
    options.max_robots = 2;
    options.max_trajectories = 3;
    options.max_scan_ranges = 100;
    options.max_future_s = 30;
    server_ = std::make_unique<ServerNode>(
        options, [](const std::string&, const std::vector<uint8_t>&) {}, [] { return kNow; });
    server_->RequireAuthentication(MakeAuth(kKeys, "server", kNow));
    ASSERT_TRUE(loop_
                    ->Subscribe("ANCHORMAP_KEYFRAMES|ANCHORMAP_ENCOUNTERS",
                                [this](const std::string& c, const uint8_t* d, size_t n) {
                                  server_->OnMessage(c, d, n);
                                })
                    .ok());
  }

  void Send(const std::string& channel, const std::vector<uint8_t>& bytes) {
    ASSERT_TRUE(loop_->Publish(channel, bytes).ok());
    loop_->HandlePending();
  }
  int64_t Accepted() const { return server_->server().stats().keyframes_received; }
  int64_t Count(ErrorCode code) const { return server_->server().rejects().count(code); }

  std::unique_ptr<LcmLoop> loop_;
  std::unique_ptr<ServerNode> server_;
};

TEST_F(AuthInjectionTest, PublisherWithoutTheKeyGetsNothingAccepted) {
  const std::string kf = "ANCHORMAP_KEYFRAMES";
  // Unsigned keyframes and encounters, as today's daemons publish them.
  for (int seq = 0; seq < 10; ++seq) Send(kf, EncodeKeyframe(MakeKeyframe("R9", 9, seq)));
  Send("ANCHORMAP_ENCOUNTERS",
       EncodeEncounter(Encounter{kNow, "R1", 1, "R9", Pose2(), Eigen::Matrix3d::Identity()}));
  EXPECT_EQ(Count(ErrorCode::kUnsigned), 11);
  // Signed under the fleet's key id with a guessed secret, and under an unknown key id.
  Authenticator guesser = MakeAuth("fleet " + std::string(64, '2'), "R9", kNow);
  Authenticator stranger = MakeAuth("mine " + std::string(64, '1'), "R9", kNow);
  for (int seq = 0; seq < 5; ++seq) {
    const std::vector<uint8_t> bytes = EncodeKeyframe(MakeKeyframe("R9", 9, seq));
    Send(kf, guesser.Seal(kf, bytes.data(), bytes.size()));
    Send(kf, stranger.Seal(kf, bytes.data(), bytes.size()));
  }
  EXPECT_EQ(Count(ErrorCode::kBadTag), 5);
  EXPECT_EQ(Count(ErrorCode::kUnknownKey), 5);
  EXPECT_EQ(Accepted(), 0);
  EXPECT_EQ(server_->server().stats().encounters_received, 0);

  // The fleet's own agent gets through; captured envelopes replayed, moved to another
  // channel or altered do not.
  Authenticator agent = MakeAuth(kKeys, "R1", kNow);
  std::vector<std::vector<uint8_t>> captured;
  for (int seq = 0; seq < 5; ++seq) {
    const std::vector<uint8_t> bytes = EncodeKeyframe(MakeKeyframe("R1", 1, seq));
    captured.push_back(agent.Seal(kf, bytes.data(), bytes.size()));
    Send(kf, captured.back());
  }
  EXPECT_EQ(Accepted(), 5);
  for (const auto& envelope : captured) Send(kf, envelope);
  EXPECT_EQ(Count(ErrorCode::kReplay), 5);
  Send("ANCHORMAP_ENCOUNTERS", agent.Seal(kf, captured[0].data(), 0));  // sealed for kf
  std::vector<uint8_t> altered = captured[4];
  altered[altered.size() / 2] ^= 0x40;
  Send(kf, altered);
  EXPECT_EQ(Count(ErrorCode::kBadTag), 7);
  EXPECT_EQ(Accepted(), 5);
}

TEST_F(AuthInjectionTest, KeyHoldersStillMeetTheClockAndTheCaps) {
  const std::string kf = "ANCHORMAP_KEYFRAMES";
  Authenticator agent = MakeAuth(kKeys, "R1", kNow);
  auto send = [&](const Keyframe& k) {
    const std::vector<uint8_t> bytes = EncodeKeyframe(k);
    Send(kf, agent.Seal(kf, bytes.data(), bytes.size()));
  };
  send(MakeKeyframe("R1", 1, 0));
  ASSERT_EQ(Accepted(), 1);
  const int64_t data_utime = server_->server().data_utime();
  Keyframe future = MakeKeyframe("R1", 1, 1);
  future.utime = future.scan.utime = 4'102'444'800'000'000;  // 2100-01-01
  send(future);
  EXPECT_EQ(Count(ErrorCode::kFromFuture), 1);
  EXPECT_EQ(server_->server().data_utime(), data_utime);  // the data clock did not move
  send(MakeKeyframe("R1", 1, 1));                         // and the next one is believed
  EXPECT_EQ(Accepted(), 2);

  Keyframe big = MakeKeyframe("R1", 1, 2);
  big.scan.ranges.assign(101, 3.0f);
  send(big);
  EXPECT_EQ(Count(ErrorCode::kCapReached), 1);
  send(MakeKeyframe("R2", 2, 0));  // second robot: within the cap of 2
  send(MakeKeyframe("R3", 3, 0));  // third robot: refused
  EXPECT_EQ(Count(ErrorCode::kCapReached), 2);
  send(MakeKeyframe("R2", 22, 0));  // third trajectory: within the cap of 3
  send(MakeKeyframe("R2", 23, 0));  // fourth: refused
  EXPECT_EQ(Count(ErrorCode::kCapReached), 3);
  for (int i = 0; i < 1000; ++i) send(MakeKeyframe("X" + std::to_string(i), 100 + i, 0));
  EXPECT_EQ(Count(ErrorCode::kCapReached), 1003);
  EXPECT_EQ(Accepted(), 4);
}

}  // namespace
}  // namespace anchormap
