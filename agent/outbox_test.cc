#include "agent/outbox.h"

#include <filesystem>

#include <gtest/gtest.h>

#include "tests/testing/scratch.h"

namespace anchormap {
namespace {

std::vector<uint8_t> Bytes(size_t n, uint8_t value = 1) { return std::vector<uint8_t>(n, value); }

std::vector<int32_t> Seqs(const std::vector<Outbox::Message>& messages) {
  std::vector<int32_t> seqs;
  for (const Outbox::Message& m : messages) seqs.push_back(m.seq);
  return seqs;
}

// Distinct bytes per message (its seq in every byte and a length that varies), so that a
// read-back from the wrong offset or of the wrong length shows.
std::vector<uint8_t> MessageBytes(int32_t seq) {
  return std::vector<uint8_t>(1000 + static_cast<size_t>(seq % 7) * 37,
                              static_cast<uint8_t>(seq * 13 + 5));
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
  EXPECT_EQ(resent[3].kind, StreamKind::kEncounters);
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

// An acknowledgement that leaves out an encounter sent at least
// encounter_resend_after_ack_s ago has it sent again at once (the server cannot ask for
// an encounter it does not know was lost); keyframes and recent encounters wait.
TEST(OutboxTest, EncountersAnAcknowledgementLeavesOutAreResentAtOnce) {
  OutboxOptions options;
  options.encounter_resend_after_ack_s = 1.0;
  Outbox outbox(options);
  ASSERT_TRUE(outbox.Add(StreamKind::kKeyframes, 0, Bytes(100), 0).ok());
  ASSERT_TRUE(outbox.Add(StreamKind::kEncounters, 0, Bytes(10), 0).ok());
  ASSERT_TRUE(outbox.Add(StreamKind::kEncounters, 1, Bytes(10), 0).ok());
  ASSERT_TRUE(outbox.Add(StreamKind::kEncounters, 2, Bytes(10), 900'000).ok());
  outbox.Acknowledge(1, 1);  // keyframe 0 and encounter 0 arrived
  const auto resent = outbox.EncountersLeftByAck(1'000'000);
  EXPECT_EQ(Seqs(resent), (std::vector<int32_t>{1}));  // 2 was sent 0.1 s ago
  EXPECT_EQ(resent[0].kind, StreamKind::kEncounters);
  EXPECT_EQ(outbox.stats().resent_after_ack, 1);
  // Marked as sent: the next acknowledgement 0.5 s later leaves both alone.
  EXPECT_TRUE(outbox.EncountersLeftByAck(1'500'000).empty());
  EXPECT_EQ(Seqs(outbox.EncountersLeftByAck(2'000'000)), (std::vector<int32_t>{1, 2}));
  options.encounter_resend_after_ack_s = 0.0;  // off
  Outbox off(options);
  ASSERT_TRUE(off.Add(StreamKind::kEncounters, 0, Bytes(10), 0).ok());
  EXPECT_TRUE(off.EncountersLeftByAck(10'000'000).empty());
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

TEST(OutboxTest, PastTheMemoryBoundTheOldestSpillToAFileAndAreResentInOrder) {
  OutboxOptions options;
  options.max_bytes = 4096;  // about three keyframes in memory
  options.spill_dir = testing::ScratchDir().string();
  options.resend_timeout_s = 1.0;
  options.max_resend_per_poll = 1000;
  Outbox outbox(options);
  // The server is away: 500 keyframes and 20 encounters, none acknowledged.
  constexpr int32_t kKeyframes = 500;
  for (int32_t s = 0; s < kKeyframes; ++s) {
    ASSERT_TRUE(outbox.Add(StreamKind::kKeyframes, s, MessageBytes(s), s).ok()) << s;
    if (s % 25 == 0) {
      ASSERT_TRUE(outbox.Add(StreamKind::kEncounters, s / 25, Bytes(40, 7), s).ok());
    }
  }
  EXPECT_EQ(outbox.size(), 520u);
  EXPECT_LE(outbox.bytes(), 4096u);
  EXPECT_EQ(outbox.stats().dropped, 0);
  EXPECT_GE(outbox.spilled_entries(), 490u);
  EXPECT_EQ(outbox.stats().spilled, static_cast<int64_t>(outbox.spilled_entries()));
  EXPECT_GT(outbox.spill_file_bytes(), 490 * 1000);
  // Nothing of it is in the folder: the file was unlinked when made.
  EXPECT_TRUE(std::filesystem::is_empty(options.spill_dir));

  // The server is back and asks for everything: all of it, in order, byte for byte.
  const auto resent = outbox.Requested(
      {{StreamKind::kKeyframes, 0, kKeyframes - 1}, {StreamKind::kEncounters, 0, 19}}, 10'000);
  ASSERT_EQ(resent.size(), 520u);
  for (int32_t s = 0; s < kKeyframes; ++s) {
    ASSERT_EQ(resent[s].kind, StreamKind::kKeyframes);
    ASSERT_EQ(resent[s].seq, s);
    ASSERT_EQ(resent[s].bytes, MessageBytes(s)) << s;
  }
  for (int32_t e = 0; e < 20; ++e) {
    EXPECT_EQ(resent[kKeyframes + e].kind, StreamKind::kEncounters);
    EXPECT_EQ(resent[kKeyframes + e].seq, e);
    EXPECT_EQ(resent[kKeyframes + e].bytes, Bytes(40, 7));
  }
  EXPECT_GE(outbox.stats().read_back, 490);
  EXPECT_EQ(outbox.stats().spill_failures, 0);

  // Timeout resends read spilled entries back too, oldest send first.
  const auto timed_out = outbox.TimedOut(3'000'000);
  ASSERT_EQ(timed_out.size(), 520u);
  EXPECT_EQ(timed_out[0].seq, 0);
  EXPECT_EQ(timed_out[0].bytes, MessageBytes(0));

  // Acknowledged in part: the file stays; acknowledged in full: it is emptied.
  outbox.Acknowledge(250, 10);
  EXPECT_EQ(outbox.size(), 260u);
  EXPECT_GT(outbox.spill_file_bytes(), 0);
  outbox.Acknowledge(kKeyframes, 20);
  EXPECT_EQ(outbox.size(), 0u);
  EXPECT_EQ(outbox.bytes(), 0u);
  EXPECT_EQ(outbox.spilled_entries(), 0u);
  EXPECT_EQ(outbox.spill_file_bytes(), 0);
  EXPECT_EQ(outbox.stats().dropped, 0);
}

TEST(OutboxTest, ASpillFileBoundDropsTheOldestInMemoryAndSaysSo) {
  OutboxOptions options;
  options.max_bytes = 2048;
  options.spill_dir = testing::ScratchDir().string();
  options.max_spill_bytes = 3000;  // three 1000-byte keyframes
  Outbox outbox(options);
  int dropped_reports = 0;
  for (int32_t s = 0; s < 10; ++s) {
    const Status status = outbox.Add(StreamKind::kKeyframes, s, Bytes(1000, s), s);
    if (!status.ok()) {
      EXPECT_EQ(status.code(), ErrorCode::kQueueFull);
      ++dropped_reports;
    }
  }
  // 3 spilled, 2 in memory, 5 dropped (the oldest in memory when the file was full).
  EXPECT_EQ(outbox.spilled_entries(), 3u);
  EXPECT_EQ(outbox.stats().dropped, 5);
  EXPECT_EQ(dropped_reports, 5);
  EXPECT_EQ(Seqs(outbox.Requested({{StreamKind::kKeyframes, 0, 9}}, 20)),
            (std::vector<int32_t>{0, 1, 2, 8, 9}));
}

TEST(OutboxTest, AnUnusableSpillFolderDropsAsWithoutOneAndReportsTheIoError) {
  OutboxOptions options;
  options.max_bytes = 2048;
  options.spill_dir = (testing::ScratchDir() / "does-not-exist").string();
  Outbox outbox(options);
  ASSERT_TRUE(outbox.Add(StreamKind::kKeyframes, 0, Bytes(1000), 0).ok());
  ASSERT_TRUE(outbox.Add(StreamKind::kKeyframes, 1, Bytes(1000), 0).ok());
  const Status status = outbox.Add(StreamKind::kKeyframes, 2, Bytes(1000), 0);
  EXPECT_EQ(status.code(), ErrorCode::kIoError);
  EXPECT_EQ(outbox.stats().dropped, 1);
  EXPECT_EQ(outbox.stats().spill_failures, 1);
  EXPECT_EQ(outbox.spill_error().code(), ErrorCode::kIoError);
  EXPECT_EQ(Seqs(outbox.Requested({{StreamKind::kKeyframes, 0, 2}}, 1)),
            (std::vector<int32_t>{1, 2}));
}

}  // namespace
}  // namespace anchormap
