#include "agent/outbox.h"

#include <gtest/gtest.h>

namespace anchormap {
namespace {

std::vector<uint8_t> Bytes(size_t n, uint8_t value = 1) { return std::vector<uint8_t>(n, value); }

std::vector<int32_t> Seqs(const std::vector<const Outbox::Entry*>& entries) {
  std::vector<int32_t> seqs;
  for (const Outbox::Entry* e : entries) seqs.push_back(e->seq);
  return seqs;
}

TEST(OutboxTest, KeepsUntilAcknowledgedAndResendsRequestedRanges) {
  Outbox outbox;
  for (int32_t s = 0; s < 10; ++s)
    ASSERT_TRUE(outbox.Add(StreamKind::kKeyframes, s, Bytes(100), 0).ok());
  ASSERT_TRUE(outbox.Add(StreamKind::kEncounters, 0, Bytes(10), 0).ok());
  ASSERT_TRUE(outbox.Add(StreamKind::kEncounters, 1, Bytes(10), 0).ok());
  EXPECT_EQ(outbox.size(), 12u);
  EXPECT_EQ(outbox.bytes(), 1020u);

  const auto resent =
      outbox.Requested({{StreamKind::kKeyframes, 2, 4}, {StreamKind::kEncounters, 1, 1}}, 5);
  EXPECT_EQ(Seqs(resent), (std::vector<int32_t>{2, 3, 4, 1}));
  EXPECT_EQ(resent[3]->kind, StreamKind::kEncounters);
  EXPECT_EQ(outbox.stats().resent_on_request, 4);

  outbox.Acknowledge(/*keyframes_next=*/5, /*encounters_next=*/1);
  EXPECT_EQ(outbox.size(), 6u);  // keyframes 5..9, encounter 1
  EXPECT_EQ(outbox.stats().acknowledged, 6);
  // Asked for what was acknowledged already: nothing to send, counted.
  EXPECT_TRUE(outbox.Requested({{StreamKind::kKeyframes, 0, 4}}, 6).empty());
  EXPECT_EQ(outbox.stats().requested_but_gone, 5);
  outbox.Acknowledge(10, 2);
  EXPECT_EQ(outbox.size(), 0u);
  EXPECT_EQ(outbox.bytes(), 0u);
}

TEST(OutboxTest, ResendsOnTimeoutWithBackOffAndAtMostAFewPerPoll) {
  OutboxOptions options;
  options.resend_timeout_s = 1.0;
  options.max_resend_per_poll = 2;
  Outbox outbox(options);
  for (int32_t s = 0; s < 3; ++s)
    ASSERT_TRUE(outbox.Add(StreamKind::kKeyframes, s, Bytes(8), s).ok());
  EXPECT_TRUE(outbox.TimedOut(999'999).empty());
  EXPECT_EQ(Seqs(outbox.TimedOut(1'000'001)), (std::vector<int32_t>{0, 1}));  // oldest first
  EXPECT_EQ(Seqs(outbox.TimedOut(1'000'002)), (std::vector<int32_t>{2}));
  // Sent twice now: the next timeout is 2 s.
  EXPECT_TRUE(outbox.TimedOut(2'500'000).empty());
  EXPECT_EQ(outbox.TimedOut(3'000'001).size(), 2u);
  EXPECT_EQ(outbox.stats().resent_on_timeout, 5);
  // A request counts as a send: no timeout resend right after it.
  outbox.Requested({{StreamKind::kKeyframes, 2, 2}}, 3'000'002);
  EXPECT_TRUE(outbox.TimedOut(3'000'003).empty());
}

TEST(OutboxTest, BoundedMemoryDropsTheOldestKeyframesAndSaysSo) {
  OutboxOptions options;
  options.max_bytes = 4096;
  Outbox outbox(options);
  ASSERT_TRUE(outbox.Add(StreamKind::kEncounters, 0, Bytes(16), 0).ok());
  for (int32_t s = 0; s < 4; ++s) {
    ASSERT_TRUE(outbox.Add(StreamKind::kKeyframes, s, Bytes(1000), 0).ok());
  }
  const Status full = outbox.Add(StreamKind::kKeyframes, 4, Bytes(1000), 0);
  EXPECT_EQ(full.code(), ErrorCode::kQueueFull);
  EXPECT_EQ(outbox.stats().dropped, 1);
  EXPECT_LE(outbox.bytes(), 4096u);
  // Keyframe 0 is gone; the encounter and keyframes 1..4 are kept.
  EXPECT_EQ(Seqs(outbox.Requested({{StreamKind::kKeyframes, 0, 4}}, 1)),
            (std::vector<int32_t>{1, 2, 3, 4}));
  EXPECT_EQ(outbox.Requested({{StreamKind::kEncounters, 0, 0}}, 1).size(), 1u);
}

}  // namespace
}  // namespace anchormap
