#include "common/bus/codec.h"

#include <cmath>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "anchormap/keyframe_v1_t.hpp"
#include "common/bus/map_codec.h"

namespace anchormap {
namespace {

LaserScan MakeScan(int n) {
  LaserScan scan;
  scan.utime = 1'000'000;
  scan.rad0 = static_cast<float>(-kPi / 2);
  scan.radstep = static_cast<float>(kPi / (n - 1));
  scan.max_range = 30.0f;
  for (int i = 0; i < n; ++i) scan.ranges.push_back(1.0f + 0.01f * static_cast<float>(i));
  scan.T_body_sensor = Pose2(0.2, 0.0, 0.1);
  return scan;
}

Keyframe MakeKeyframe() {
  Keyframe k;
  k.robot = "R2";
  k.trajectory_id = 1'700'000'000'000'000;
  k.seq = 7;
  k.encounters_relayed = 3;
  k.utime = 5'000'000;
  k.T_local_pose = Pose2(1.5, -2.0, 0.3);
  k.T_previous_this = Pose2(0.5, 0.01, 0.02);
  k.T_previous_this_covariance = Eigen::Vector3d(0.01, 0.02, 0.003).asDiagonal();
  k.T_previous_this_covariance(0, 1) = k.T_previous_this_covariance(1, 0) = 0.001;
  k.scan = MakeScan(181);
  k.scan.utime = k.utime;
  return k;
}

// Writes a big-endian int32 at `offset` (to forge length fields).
void PatchInt32(std::vector<uint8_t>* bytes, size_t offset, int32_t value) {
  const auto v = static_cast<uint32_t>(value);
  (*bytes)[offset] = static_cast<uint8_t>(v >> 24);
  (*bytes)[offset + 1] = static_cast<uint8_t>(v >> 16);
  (*bytes)[offset + 2] = static_cast<uint8_t>(v >> 8);
  (*bytes)[offset + 3] = static_cast<uint8_t>(v);
}

TEST(CodecTest, OdometryRoundTripsYawThroughTheQuaternion) {
  const auto bytes = EncodeOdometry({123, Pose2(1.0, -2.0, 2.5)});
  const auto decoded = DecodeOdometry(bytes.data(), bytes.size());
  ASSERT_TRUE(decoded.ok()) << decoded.status().message();
  EXPECT_EQ(decoded->utime, 123);
  EXPECT_DOUBLE_EQ(decoded->T_odom_body.x(), 1.0);
  EXPECT_DOUBLE_EQ(decoded->T_odom_body.y(), -2.0);
  EXPECT_NEAR(decoded->T_odom_body.theta(), 2.5, 1e-12);
}

TEST(CodecTest, OdometryRejectsNanBadQuaternionTruncationAndWrongType) {
  auto bytes = EncodeOdometry({1, Pose2(std::numeric_limits<double>::quiet_NaN(), 0, 0)});
  EXPECT_EQ(DecodeOdometry(bytes.data(), bytes.size()).status().code(), ErrorCode::kNotFinite);

  bytes = EncodeOdometry({1, Pose2(0, 0, 0)});
  // orientation[0] (w) sits after hash 8 + utime 8 + pos 24 + vel 24: make it 0.
  for (size_t i = 64; i < 72; ++i) bytes[i] = 0;
  const auto zero_quaternion = DecodeOdometry(bytes.data(), bytes.size());
  EXPECT_FALSE(zero_quaternion.ok());
  EXPECT_EQ(zero_quaternion.status().code(), ErrorCode::kInvalidValue);

  bytes = EncodeOdometry({1, Pose2(0, 0, 0)});
  EXPECT_EQ(DecodeOdometry(bytes.data(), bytes.size() - 1).status().code(),
            ErrorCode::kDecodeFailed);
  const auto laser = EncodeLaser(MakeScan(10));
  const auto wrong = DecodeOdometry(laser.data(), laser.size());
  EXPECT_EQ(wrong.status().code(), ErrorCode::kDecodeFailed);
  EXPECT_NE(wrong.status().message().find("fingerprint"), std::string::npos)
      << wrong.status().message();
  EXPECT_EQ(DecodeOdometry(nullptr, 0).status().code(), ErrorCode::kDecodeFailed);
}

TEST(CodecTest, LaserRoundTripsWithoutMaxRangeAndOffset) {
  LaserScan scan = MakeScan(361);
  scan.max_range = 25.0f;
  scan.T_body_sensor = Pose2(0.1, 0.2, 0.3);
  const auto bytes = EncodeLaser(scan);
  const auto decoded = DecodeLaser(bytes.data(), bytes.size());
  ASSERT_TRUE(decoded.ok()) << decoded.status().message();
  EXPECT_EQ(decoded->ranges, scan.ranges);
  EXPECT_EQ(decoded->utime, scan.utime);
  EXPECT_FLOAT_EQ(decoded->radstep, scan.radstep);
  // Not on the wire: the agent sets both from its flags.
  EXPECT_EQ(decoded->max_range, 0.0f);
  EXPECT_EQ(decoded->T_body_sensor.y(), 0.0);
}

TEST(CodecTest, LaserRejectsNanRangeZeroStepAndAbsurdCountWithoutAllocating) {
  LaserScan scan = MakeScan(50);
  scan.ranges[17] = std::numeric_limits<float>::quiet_NaN();
  auto bytes = EncodeLaser(scan);
  auto decoded = DecodeLaser(bytes.data(), bytes.size());
  EXPECT_EQ(decoded.status().code(), ErrorCode::kNotFinite);
  EXPECT_NE(decoded.status().message().find("range 17"), std::string::npos);

  scan = MakeScan(50);
  scan.radstep = 0.0f;
  bytes = EncodeLaser(scan);
  EXPECT_EQ(DecodeLaser(bytes.data(), bytes.size()).status().code(), ErrorCode::kInvalidValue);

  // nranges sits after hash 8 + utime 8. 2^31 - 1 ranges would be an 8 GB resize inside
  // lcm-gen's decoder; the pre-flight check refuses it first.
  bytes = EncodeLaser(MakeScan(3));
  PatchInt32(&bytes, 16, std::numeric_limits<int32_t>::max());
  EXPECT_EQ(DecodeLaser(bytes.data(), bytes.size()).status().code(), ErrorCode::kAbsurdSize);
  PatchInt32(&bytes, 16, -5);
  EXPECT_EQ(DecodeLaser(bytes.data(), bytes.size()).status().code(), ErrorCode::kAbsurdSize);
  PatchInt32(&bytes, 16, 5000);  // plausible count, but the bytes are not there
  EXPECT_EQ(DecodeLaser(bytes.data(), bytes.size()).status().code(), ErrorCode::kDecodeFailed);
  scan = MakeScan(CodecLimits::kMaxRanges + 1);
  scan.radstep = 1e-4f;
  bytes = EncodeLaser(scan);
  EXPECT_EQ(DecodeLaser(bytes.data(), bytes.size()).status().code(), ErrorCode::kAbsurdSize);
}

TEST(CodecTest, KeyframeRoundTripsEveryField) {
  const Keyframe k = MakeKeyframe();
  const auto bytes = EncodeKeyframe(k);
  const auto decoded = DecodeKeyframe(bytes.data(), bytes.size());
  ASSERT_TRUE(decoded.ok()) << decoded.status().message();
  const Keyframe& d = *decoded;
  EXPECT_EQ(d.robot, "R2");
  EXPECT_EQ(d.trajectory_id, k.trajectory_id);
  EXPECT_EQ(d.seq, 7);
  EXPECT_EQ(d.encounters_relayed, 3);
  EXPECT_EQ(d.utime, 5'000'000);
  EXPECT_DOUBLE_EQ(d.T_local_pose.y(), -2.0);
  EXPECT_DOUBLE_EQ(d.T_previous_this.theta(), 0.02);
  EXPECT_DOUBLE_EQ(d.T_previous_this_covariance(1, 0), 0.001);
  EXPECT_DOUBLE_EQ(d.T_previous_this_covariance(2, 2), 0.003);
  EXPECT_EQ(d.scan.ranges, k.scan.ranges);
  EXPECT_EQ(d.scan.utime, k.utime);
  EXPECT_FLOAT_EQ(d.scan.max_range, 30.0f);
  EXPECT_DOUBLE_EQ(d.scan.T_body_sensor.x(), 0.2);
}

TEST(CodecTest, KeyframeRejectsEachKindOfBadContent) {
  Keyframe k = MakeKeyframe();
  k.robot = "";
  auto bytes = EncodeKeyframe(k);
  EXPECT_EQ(DecodeKeyframe(bytes.data(), bytes.size()).status().code(), ErrorCode::kEmptyRobotName);

  k = MakeKeyframe();
  k.seq = -1;
  bytes = EncodeKeyframe(k);
  EXPECT_EQ(DecodeKeyframe(bytes.data(), bytes.size()).status().code(), ErrorCode::kBadSequence);

  k = MakeKeyframe();
  k.encounters_relayed = -1;
  bytes = EncodeKeyframe(k);
  const Status negative_count = DecodeKeyframe(bytes.data(), bytes.size()).status();
  EXPECT_EQ(negative_count.code(), ErrorCode::kBadSequence);
  EXPECT_NE(negative_count.message().find("encounters_relayed"), std::string::npos);

  k = MakeKeyframe();
  k.T_previous_this_covariance(2, 2) = -0.1;
  bytes = EncodeKeyframe(k);
  EXPECT_EQ(DecodeKeyframe(bytes.data(), bytes.size()).status().code(),
            ErrorCode::kCovarianceNotSpd);

  k = MakeKeyframe();
  k.T_previous_this_covariance(0, 2) = 0.5;  // not symmetric
  bytes = EncodeKeyframe(k);
  EXPECT_EQ(DecodeKeyframe(bytes.data(), bytes.size()).status().code(),
            ErrorCode::kCovarianceNotSpd);

  k = MakeKeyframe();
  k.T_local_pose = Pose2(std::numeric_limits<double>::infinity(), 0, 0);
  bytes = EncodeKeyframe(k);
  EXPECT_EQ(DecodeKeyframe(bytes.data(), bytes.size()).status().code(), ErrorCode::kNotFinite);

  k = MakeKeyframe();
  k.robot = std::string(200, 'R');
  bytes = EncodeKeyframe(k);
  EXPECT_EQ(DecodeKeyframe(bytes.data(), bytes.size()).status().code(), ErrorCode::kAbsurdSize);

  // The robot string's length field (after hash 8 + utime 8) forged to 0 and to -3.
  bytes = EncodeKeyframe(MakeKeyframe());
  PatchInt32(&bytes, 16, 0);
  EXPECT_EQ(DecodeKeyframe(bytes.data(), bytes.size()).status().code(), ErrorCode::kDecodeFailed);
  PatchInt32(&bytes, 16, -3);
  EXPECT_EQ(DecodeKeyframe(bytes.data(), bytes.size()).status().code(), ErrorCode::kDecodeFailed);

  bytes = EncodeKeyframe(MakeKeyframe());
  bytes.push_back(0);  // trailing garbage
  EXPECT_EQ(DecodeKeyframe(bytes.data(), bytes.size()).status().code(), ErrorCode::kDecodeFailed);
}

// Journals written before keyframe_t carried encounters_relayed hold the older layout
// (anchormap.keyframe_v1_t, the same fingerprint as keyframe_t had): read, with a count of 0
// (it reveals nothing), and checked like the new one.
TEST(CodecTest, TheLayoutBeforeTheRelayCountIsStillRead) {
  anchormap::keyframe_v1_t old;
  old.utime = 5'000'000;
  old.robot = "R2";
  old.trajectory_id = 99;
  old.seq = 7;
  const double pose[3] = {1.5, -2.0, 0.3};
  const double delta[3] = {0.5, 0.01, 0.02};
  const double covariance[9] = {0.01, 0, 0, 0, 0.02, 0, 0, 0, 0.003};
  const double offset[3] = {0.2, 0, 0};
  std::copy(pose, pose + 3, old.pose);
  std::copy(delta, delta + 3, old.T_previous_this);
  std::copy(covariance, covariance + 9, old.T_previous_this_covariance);
  std::copy(offset, offset + 3, old.sensor_offset);
  old.rad0 = -1.5f;
  old.radstep = 0.01f;
  old.max_range = 30.0f;
  old.nranges = 3;
  old.ranges = {1.0f, 2.0f, 3.0f};
  std::vector<uint8_t> bytes(static_cast<size_t>(old.getEncodedSize()));
  ASSERT_EQ(old.encode(bytes.data(), 0, static_cast<int>(bytes.size())),
            static_cast<int>(bytes.size()));
  const Result<Keyframe> decoded = DecodeKeyframe(bytes.data(), bytes.size());
  ASSERT_TRUE(decoded.ok()) << decoded.status().message();
  EXPECT_EQ(decoded->seq, 7);
  EXPECT_EQ(decoded->trajectory_id, 99);
  EXPECT_EQ(decoded->encounters_relayed, 0);
  EXPECT_DOUBLE_EQ(decoded->T_previous_this.theta(), 0.02);
  EXPECT_EQ(decoded->scan.ranges, old.ranges);
  // Re-encoded, it is the new layout (4 bytes more: the count).
  EXPECT_EQ(EncodeKeyframe(*decoded).size(), bytes.size() + 4);
  old.seq = -2;
  ASSERT_EQ(old.encode(bytes.data(), 0, static_cast<int>(bytes.size())),
            static_cast<int>(bytes.size()));
  EXPECT_EQ(DecodeKeyframe(bytes.data(), bytes.size()).status().code(), ErrorCode::kBadSequence);
  bytes.pop_back();
  EXPECT_EQ(DecodeKeyframe(bytes.data(), bytes.size()).status().code(), ErrorCode::kDecodeFailed);
}

TEST(CodecTest, EncounterRoundTripsAndRejectsSelfAndBadCovariance) {
  Encounter e;
  e.utime = 42;
  e.observer = "R1";
  e.observer_trajectory_id = 99;
  e.observed = "R3";
  e.T_observer_observed = Pose2(2.0, 0.5, -0.4);
  e.covariance = Eigen::Vector3d(0.04, 0.04, 0.01).asDiagonal();
  e.seq = 17;
  auto bytes = EncodeEncounter(e);
  auto decoded = DecodeEncounter(bytes.data(), bytes.size());
  ASSERT_TRUE(decoded.ok()) << decoded.status().message();
  EXPECT_EQ(decoded->seq, 17);
  EXPECT_EQ(decoded->observer, "R1");
  EXPECT_EQ(decoded->observed, "R3");
  EXPECT_EQ(decoded->observer_trajectory_id, 99);
  EXPECT_DOUBLE_EQ(decoded->T_observer_observed.theta(), -0.4);
  EXPECT_DOUBLE_EQ(decoded->covariance(2, 2), 0.01);

  Encounter unsequenced = e;
  unsequenced.seq = -2;
  bytes = EncodeEncounter(unsequenced);
  EXPECT_EQ(DecodeEncounter(bytes.data(), bytes.size()).status().code(), ErrorCode::kBadSequence);

  Encounter self = e;
  self.observed = "R1";
  bytes = EncodeEncounter(self);
  EXPECT_EQ(DecodeEncounter(bytes.data(), bytes.size()).status().code(), ErrorCode::kSelfEncounter);

  Encounter bad = e;
  bad.covariance.setZero();
  bytes = EncodeEncounter(bad);
  EXPECT_EQ(DecodeEncounter(bytes.data(), bytes.size()).status().code(),
            ErrorCode::kCovarianceNotSpd);

  Encounter unnamed = e;
  unnamed.observed = "";
  bytes = EncodeEncounter(unnamed);
  EXPECT_EQ(DecodeEncounter(bytes.data(), bytes.size()).status().code(),
            ErrorCode::kEmptyRobotName);
}

// Mutated and truncated messages of every input type: decoding must return (a value or a
// reason), never crash or throw; ASan builds check the memory side. Each accepted message
// is a fixed point after one re-encoding (decode(encode(v)) == v, compared as bytes), and
// each refusal carries one of the input-refusal codes.
template <typename T, typename Decode, typename Encode>
bool CheckOne(const std::vector<uint8_t>& bytes, Decode decode, Encode encode) {
  const Result<T> value = decode(bytes.data(), bytes.size());
  if (!value.ok()) {
    const int code = static_cast<int>(value.status().code());
    EXPECT_GE(code, static_cast<int>(ErrorCode::kDecodeFailed));
    EXPECT_LT(code, static_cast<int>(ErrorCode::kInvalidArgument)) << value.status().ToString();
    EXPECT_FALSE(value.status().message().empty());
    return false;
  }
  const std::vector<uint8_t> once = encode(*value);
  const Result<T> again = decode(once.data(), once.size());
  EXPECT_TRUE(again.ok()) << again.status().ToString();
  if (again.ok()) {
    EXPECT_EQ(encode(*again), once);
  }
  return true;
}

TEST(CodecTest, RandomCorruptionNeverCrashes) {
  std::mt19937 rng(7);
  const std::vector<std::vector<uint8_t>> originals = {
      EncodeKeyframe(MakeKeyframe()), EncodeLaser(MakeScan(90)),
      EncodeOdometry({5, Pose2(1, 2, 3)}),
      EncodeEncounter(Encounter{1, "A", 0, "B", Pose2(), Eigen::Matrix3d::Identity()})};
  int rejected = 0, accepted = 0;
  for (int trial = 0; trial < 4000; ++trial) {
    std::vector<uint8_t> bytes = originals[trial % originals.size()];
    std::uniform_int_distribution<size_t> position(0, bytes.size() - 1);
    const int flips = 1 + trial % 4;
    for (int f = 0; f < flips; ++f) bytes[position(rng)] = static_cast<uint8_t>(rng());
    if (trial % 5 == 0) bytes.resize(position(rng));
    // Every decoder sees every input (no short-circuit): count the ones that accept it.
    const int accepting = int{CheckOne<Keyframe>(bytes, DecodeKeyframe, EncodeKeyframe)} +
                          int{CheckOne<LaserScan>(bytes, DecodeLaser, EncodeLaser)} +
                          int{CheckOne<OdometrySample>(bytes, DecodeOdometry, EncodeOdometry)} +
                          int{CheckOne<Encounter>(bytes, DecodeEncounter, EncodeEncounter)};
    const bool ok = accepting > 0;
    if (!ok) ++rejected;
    if (ok) ++accepted;
  }
  // Flipping bytes inside float payloads often leaves a valid message; most are refused.
  EXPECT_GT(rejected, 1000);
  EXPECT_GT(accepted, 100);  // the round-trip property was exercised
}

TEST(CodecTest, RefusesNegativeRangesUnterminatedNamesAndAbsurdTimes) {
  Keyframe k = MakeKeyframe();
  k.scan.ranges[3] = -1.0f;
  std::vector<uint8_t> bytes = EncodeKeyframe(k);
  EXPECT_EQ(DecodeKeyframe(bytes.data(), bytes.size()).status().code(), ErrorCode::kInvalidValue);
  LaserScan scan = MakeScan(10);
  scan.ranges[0] = -0.5f;
  bytes = EncodeLaser(scan);
  EXPECT_EQ(DecodeLaser(bytes.data(), bytes.size()).status().code(), ErrorCode::kInvalidValue);

  // robot "R2": fingerprint 8, utime 8, length 4 (= 3), 'R' '2' NUL at 20..22.
  bytes = EncodeKeyframe(MakeKeyframe());
  ASSERT_EQ(bytes[22], 0);
  bytes[22] = 'X';
  const Result<Keyframe> unterminated = DecodeKeyframe(bytes.data(), bytes.size());
  EXPECT_EQ(unterminated.status().code(), ErrorCode::kDecodeFailed);
  EXPECT_NE(unterminated.status().message().find("NUL"), std::string::npos);

  k = MakeKeyframe();
  k.utime = std::numeric_limits<int64_t>::max();
  bytes = EncodeKeyframe(k);
  EXPECT_EQ(DecodeKeyframe(bytes.data(), bytes.size()).status().code(), ErrorCode::kInvalidValue);
  bytes = EncodeOdometry({std::numeric_limits<int64_t>::max(), Pose2()});
  EXPECT_EQ(DecodeOdometry(bytes.data(), bytes.size()).status().code(), ErrorCode::kInvalidValue);
  bytes = EncodeEncounter(Encounter{std::numeric_limits<int64_t>::max(), "A", 0, "B", Pose2(),
                                    Eigen::Matrix3d::Identity()});
  EXPECT_EQ(DecodeEncounter(bytes.data(), bytes.size()).status().code(), ErrorCode::kInvalidValue);
  k.utime = CodecLimits::kMaxUtime;
  bytes = EncodeKeyframe(k);
  EXPECT_TRUE(DecodeKeyframe(bytes.data(), bytes.size()).ok());
}

}  // namespace
}  // namespace anchormap
