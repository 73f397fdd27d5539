#include "common/bus/delivery_codec.h"

#include <random>

#include <gtest/gtest.h>

#include "common/bus/codec.h"

namespace anchormap {
namespace {

TEST(DeliveryCodecTest, AckAndResendRequestRoundTrip) {
  DeliveryAck ack;
  ack.utime = 5;
  ack.robot = "R2";
  ack.trajectory_id = -7;
  ack.keyframes_next = 120;
  ack.encounters_next = 3;
  auto bytes = EncodeDeliveryAck(ack);
  const Result<DeliveryAck> a = DecodeDeliveryAck(bytes.data(), bytes.size());
  ASSERT_TRUE(a.ok()) << a.status().ToString();
  EXPECT_EQ(a->robot, "R2");
  EXPECT_EQ(a->trajectory_id, -7);
  EXPECT_EQ(a->keyframes_next, 120);
  EXPECT_EQ(a->encounters_next, 3);

  ResendRequest request;
  request.utime = 9;
  request.robot = "R1";
  request.trajectory_id = 44;
  request.ranges = {{StreamKind::kKeyframes, 3, 5}, {StreamKind::kEncounters, 0, 0}};
  bytes = EncodeResendRequest(request);
  const Result<ResendRequest> r = DecodeResendRequest(bytes.data(), bytes.size());
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->trajectory_id, 44);
  EXPECT_EQ(r->ranges, request.ranges);
}

TEST(DeliveryCodecTest, RefusesBadRangesNegativeAcksAndOtherTypes) {
  ResendRequest request;
  request.robot = "R1";
  request.ranges = {{StreamKind::kKeyframes, 5, 3}};
  auto bytes = EncodeResendRequest(request);
  EXPECT_EQ(DecodeResendRequest(bytes.data(), bytes.size()).status().code(),
            ErrorCode::kBadSequence);
  request.ranges = {{static_cast<StreamKind>(2), 1, 3}};
  bytes = EncodeResendRequest(request);
  EXPECT_EQ(DecodeResendRequest(bytes.data(), bytes.size()).status().code(),
            ErrorCode::kInvalidValue);
  DeliveryAck ack;
  ack.robot = "R1";
  ack.keyframes_next = -1;
  bytes = EncodeDeliveryAck(ack);
  EXPECT_EQ(DecodeDeliveryAck(bytes.data(), bytes.size()).status().code(), ErrorCode::kBadSequence);
  ack.keyframes_next = 0;
  ack.robot = "";
  bytes = EncodeDeliveryAck(ack);
  EXPECT_EQ(DecodeDeliveryAck(bytes.data(), bytes.size()).status().code(),
            ErrorCode::kEmptyRobotName);
  // An encounter is not an ack.
  Encounter e;
  e.observer = "R1";
  e.observed = "R2";
  bytes = EncodeEncounter(e);
  EXPECT_EQ(DecodeDeliveryAck(bytes.data(), bytes.size()).status().code(),
            ErrorCode::kDecodeFailed);
}

TEST(DeliveryCodecTest, TruncatedAndCorruptedNeverCrash) {
  ResendRequest request;
  request.robot = "R1";
  for (int i = 0; i < 20; ++i) request.ranges.push_back({StreamKind::kKeyframes, i, i});
  const auto good = EncodeResendRequest(request);
  for (size_t n = 0; n < good.size(); ++n) {
    EXPECT_FALSE(DecodeResendRequest(good.data(), n).ok()) << n;
  }
  std::mt19937 rng(1);
  for (int trial = 0; trial < 2000; ++trial) {
    auto bytes = good;
    bytes[rng() % bytes.size()] = static_cast<uint8_t>(rng());
    (void)DecodeResendRequest(bytes.data(), bytes.size());
  }
}

}  // namespace
}  // namespace anchormap
