#include "common/bus/authenticator.h"

#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

const std::string kFleet = "fleet " + std::string(64, 'a') + "\n";

Authenticator Make(const std::string& keys, const std::string& sender, int64_t first = 100,
                   int window = 1024) {
  Result<KeyRing> ring = ParseKeyRing(keys);
  EXPECT_TRUE(ring.ok()) << ring.status().ToString();
  AuthenticatorOptions options;
  options.sender = sender;
  options.first_counter = first;
  options.replay_window = window;
  Result<Authenticator> auth = Authenticator::Create(std::move(*ring), options);
  EXPECT_TRUE(auth.ok()) << auth.status().ToString();
  return std::move(*auth);
}

std::vector<uint8_t> Bytes(const std::string& text) { return {text.begin(), text.end()}; }

TEST(AuthenticatorTest, ParsesKeyFilesAndRefusesBadOnes) {
  Result<KeyRing> ring = ParseKeyRing("# fleet keys\n\nR1 " + std::string(64, '0') +
                                      "  # robot 1\nR2 " + std::string(66, 'F') + "\n");
  ASSERT_TRUE(ring.ok()) << ring.status().ToString();
  EXPECT_EQ(ring->keys.size(), 2u);
  EXPECT_EQ(ring->first_id, "R1");
  EXPECT_EQ(ring->keys.at("R2").size(), 33u);
  EXPECT_FALSE(ParseKeyRing("").ok());
  EXPECT_FALSE(ParseKeyRing("R1 " + std::string(62, '0')).ok());         // 31 bytes: short
  EXPECT_FALSE(ParseKeyRing("R1 " + std::string(63, '0')).ok());         // odd
  EXPECT_FALSE(ParseKeyRing("R1 " + std::string(64, 'g')).ok());         // not hex
  EXPECT_FALSE(ParseKeyRing("R1 " + std::string(64, '0') + " x").ok());  // extra field
  EXPECT_FALSE(ParseKeyRing(kFleet + kFleet).ok());                      // duplicate id
  EXPECT_FALSE(LoadKeyFile("/nonexistent/keys").ok());
}

TEST(AuthenticatorTest, OpensWhatItSealsOnTheSameChannelOnly) {
  Authenticator sender = Make(kFleet, "R1");
  Authenticator receiver = Make(kFleet, "server");
  const std::vector<uint8_t> payload = Bytes("keyframe bytes");
  const std::vector<uint8_t> sealed = sender.Seal("KEYFRAMES", payload.data(), payload.size());
  const std::vector<uint8_t> other = sender.Seal("KEYFRAMES", payload.data(), payload.size());
  EXPECT_EQ(receiver.Open("ENCOUNTERS", sealed.data(), sealed.size()).status().code(),
            ErrorCode::kBadTag);
  Result<std::vector<uint8_t>> opened = receiver.Open("KEYFRAMES", sealed.data(), sealed.size());
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  EXPECT_EQ(*opened, payload);
  EXPECT_EQ(receiver.Open("KEYFRAMES", sealed.data(), sealed.size()).status().code(),
            ErrorCode::kReplay);
  EXPECT_TRUE(receiver.Open("KEYFRAMES", other.data(), other.size()).ok());
  // Unsigned bytes, a wrong secret under the same id, an unknown id.
  EXPECT_EQ(receiver.Open("KEYFRAMES", payload.data(), payload.size()).status().code(),
            ErrorCode::kUnsigned);
  Authenticator forger = Make("fleet " + std::string(64, 'b'), "R1", 1'000'000);
  std::vector<uint8_t> forged = forger.Seal("KEYFRAMES", payload.data(), payload.size());
  EXPECT_EQ(receiver.Open("KEYFRAMES", forged.data(), forged.size()).status().code(),
            ErrorCode::kBadTag);
  Authenticator stranger = Make("other " + std::string(64, 'a'), "R1", 1'000'000);
  forged = stranger.Seal("KEYFRAMES", payload.data(), payload.size());
  EXPECT_EQ(receiver.Open("KEYFRAMES", forged.data(), forged.size()).status().code(),
            ErrorCode::kUnknownKey);
}

// Every single-byte change of an envelope is refused (and does not spend its counter).
TEST(AuthenticatorTest, RefusesEveryAlteredByte) {
  Authenticator sender = Make(kFleet, "R1");
  Authenticator receiver = Make(kFleet, "server");
  const std::vector<uint8_t> payload = Bytes("0123456789");
  const std::vector<uint8_t> sealed = sender.Seal("C", payload.data(), payload.size());
  for (size_t i = 0; i < sealed.size(); ++i) {
    std::vector<uint8_t> bytes = sealed;
    bytes[i] ^= 0x01;
    EXPECT_FALSE(receiver.Open("C", bytes.data(), bytes.size()).ok()) << "byte " << i;
  }
  for (size_t n = 0; n < sealed.size(); ++n) {
    EXPECT_FALSE(receiver.Open("C", sealed.data(), n).ok()) << "truncated to " << n;
  }
  EXPECT_TRUE(receiver.Open("C", sealed.data(), sealed.size()).ok());
}

TEST(AuthenticatorTest, AcceptsReorderingWithinTheWindowOnce) {
  Authenticator sender = Make(kFleet, "R1", 100);
  Authenticator receiver = Make(kFleet, "server", 1, /*window=*/8);
  const std::vector<uint8_t> payload = Bytes("x");
  std::vector<std::vector<uint8_t>> sealed;
  for (int i = 0; i < 20; ++i) sealed.push_back(sender.Seal("C", payload.data(), payload.size()));
  auto open = [&](int i) { return receiver.Open("C", sealed[i].data(), sealed[i].size()); };
  EXPECT_TRUE(open(5).ok());
  EXPECT_TRUE(open(3).ok());  // late, inside the window
  EXPECT_TRUE(open(4).ok());
  EXPECT_EQ(open(3).status().code(), ErrorCode::kReplay);
  EXPECT_TRUE(open(15).ok());  // jumps ahead by 10: 5..7 fall out of the window
  EXPECT_EQ(open(6).status().code(), ErrorCode::kReplay);
  EXPECT_TRUE(open(9).ok());
  EXPECT_EQ(open(9).status().code(), ErrorCode::kReplay);
  EXPECT_EQ(open(15).status().code(), ErrorCode::kReplay);
  // A second sender under the same key has its own window.
  Authenticator second = Make(kFleet, "R2", 100);
  const std::vector<uint8_t> r2 = second.Seal("C", payload.data(), payload.size());
  EXPECT_TRUE(receiver.Open("C", r2.data(), r2.size()).ok());
  EXPECT_EQ(receiver.senders(), 2u);
}

}  // namespace
}  // namespace anchormap
