#include "server/snapshot_codec.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "common/util/log.h"
#include "tests/testing/map_difference.h"

namespace anchormap {
namespace {

// One delivery to the server as an online bus makes it: at `clock` (wall time), a keyframe,
// an encounter, or a timer tick.
struct Delivery {
  int64_t clock = 0;
  enum class Kind { kKeyframe, kEncounter, kTick } kind = Kind::kTick;
  Keyframe keyframe;
  Encounter encounter;
};

// Three robots on random walks (noisy odometry) (keyframes every 0.5 s), an encounter every 2.5 s
// between two of them (relayed, with sequence numbers), delivered as a lossy bus would:
// each message 0.1-0.4 s late (so neighbours swap), 10 % lost and resent 3 s later,
// 5 % duplicated; a timer tick every 0.1 s. The server then holds inputs in every stage
// (gaps in the delivery table, the canonical order's settle time, encounters waiting for
// their keyframes) at most moments.
std::vector<Delivery> LossyMission(double duration_s, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::vector<Delivery> out;
  auto deliver = [&](Delivery d, int64_t sent) {
    d.clock = sent + static_cast<int64_t>(1e5 + 3e5 * unit(rng));
    if (unit(rng) < 0.1) d.clock += 3'000'000;  // lost, resent
    if (unit(rng) < 0.05) out.push_back(d);     // duplicated
    out.push_back(d);
  };
  const std::string names[] = {"R1", "R2", "R3"};
  std::vector<Pose2> odometry(3);
  std::vector<Pose2> truth = {Pose2(0, 0, 0), Pose2(6, 1, 1.5), Pose2(2, 7, -1.5)};
  std::vector<int32_t> encounter_seq(3, 0);
  const int steps = static_cast<int>(duration_s / 0.5);
  for (int s = 0; s <= steps; ++s) {
    const int64_t utime = 1'000'000 + 500'000LL * s;
    for (int r = 0; r < 3; ++r) {
      Delivery d;
      d.kind = Delivery::Kind::kKeyframe;
      Keyframe& k = d.keyframe;
      k.robot = names[r];
      k.trajectory_id = 77 + r;
      k.seq = s;
      k.utime = utime;
      if (s > 0) {
        const Pose2 delta(0.5, 0.0, 0.1 * normal(rng));
        truth[r] = Compose(truth[r], delta);
        // One draw per statement (a call's argument order is unspecified; gcc's order kept).
        const double theta_noise = normal(rng);
        const double y_noise = normal(rng);
        const double x_noise = normal(rng);
        k.T_previous_this = Pose2(delta.x() + 0.02 * x_noise, delta.y() + 0.02 * y_noise,
                                  delta.theta() + 0.01 * theta_noise);
        k.T_previous_this_covariance = Eigen::Vector3d(4e-4, 4e-4, 1e-4).asDiagonal();
        odometry[r] = Compose(odometry[r], k.T_previous_this);
      }
      k.T_local_pose = odometry[r];
      k.scan.rad0 = -1.5f;
      k.scan.radstep = 0.01f;
      k.scan.max_range = 30.0f;
      k.scan.ranges.assign(30, static_cast<float>(2.0 + unit(rng)));
      deliver(d, utime);
    }
    if (s > 0 && s % 5 == 0) {
      const int observer = static_cast<int>(rng() % 3);
      const int observed = (observer + 1 + static_cast<int>(rng() % 2)) % 3;
      Delivery d;
      d.kind = Delivery::Kind::kEncounter;
      Encounter& e = d.encounter;
      e.utime = utime;
      e.observer = names[observer];
      e.observer_trajectory_id = 77 + observer;
      e.observed = names[observed];
      const Pose2 seen = Between(truth[observer], truth[observed]);
      const double theta_noise = normal(rng);
      const double y_noise = normal(rng);
      const double x_noise = normal(rng);
      e.T_observer_observed = Pose2(seen.x() + 0.05 * x_noise, seen.y() + 0.05 * y_noise,
                                    seen.theta() + 0.02 * theta_noise);
      e.covariance = Eigen::Vector3d(2.5e-3, 2.5e-3, 4e-4).asDiagonal();
      e.seq = encounter_seq[observer]++;
      deliver(d, utime);
    }
  }
  const int64_t end = 1'000'000 + 500'000LL * steps + 5'000'000;
  for (int64_t clock = 1'000'000; clock <= end; clock += 100'000) {
    Delivery tick;
    tick.clock = clock;
    out.push_back(tick);
  }
  std::stable_sort(out.begin(), out.end(),
                   [](const Delivery& a, const Delivery& b) { return a.clock < b.clock; });
  return out;
}

void Apply(MappingServer* server, const Delivery& d) {
  switch (d.kind) {
    case Delivery::Kind::kKeyframe:
      server->SetClock(d.clock);
      (void)server->OnKeyframe(d.keyframe);  // duplicates are refused (counted)
      break;
    case Delivery::Kind::kEncounter:
      server->SetClock(d.clock);
      (void)server->OnEncounter(d.encounter);
      break;
    case Delivery::Kind::kTick:
      server->Tick(d.clock);
      break;
  }
}

MappingServerOptions Options() {
  MappingServerOptions options;
  options.smoother.convergence_step = 1e-12;  // batch steps iterate to the minimum
  options.publish.grid.resolution_m = 0.2;
  return options;
}

// Everything but the estimate: tables, delivery, order stage, links, counters.
void ExpectSameState(const MappingServer& a, const MappingServer& b) {
  // Every counter, waiting item and refusal (the last update's time aside).
  auto without_time = [](std::string line) {
    const size_t from = line.find("last update ");
    return line.erase(from, line.find(" ms", from) - from);
  };
  EXPECT_EQ(without_time(a.StatusLine()), without_time(b.StatusLine()));
  EXPECT_EQ(a.stats().updates, b.stats().updates);
  EXPECT_EQ(a.stats().keyframes_received, b.stats().keyframes_received);
  EXPECT_EQ(a.stats().encounters_received, b.stats().encounters_received);
  EXPECT_EQ(a.stats().added_by_kind, b.stats().added_by_kind);
  EXPECT_EQ(a.encounter_links(), b.encounter_links());
  EXPECT_EQ(a.order_stats().released, b.order_stats().released);
  EXPECT_EQ(a.order_stats().peak_held, b.order_stats().peak_held);
  EXPECT_EQ(a.table().num_keyframes(), b.table().num_keyframes());
  EXPECT_EQ(a.receipt().num_keyframes(), b.receipt().num_keyframes());
  EXPECT_EQ(a.rejects().NonZero(), b.rejects().NonZero());
  const std::vector<DeliveryAck> acks_a = a.BuildAcks();
  const std::vector<DeliveryAck> acks_b = b.BuildAcks();
  ASSERT_EQ(acks_a.size(), acks_b.size());
  for (size_t i = 0; i < acks_a.size(); ++i) {
    EXPECT_EQ(acks_a[i].robot, acks_b[i].robot);
    EXPECT_EQ(acks_a[i].trajectory_id, acks_b[i].trajectory_id);
    EXPECT_EQ(acks_a[i].keyframes_next, acks_b[i].keyframes_next);
    EXPECT_EQ(acks_a[i].encounters_next, acks_b[i].encounters_next);
  }
  for (size_t t = 0; t < a.table().records().size(); ++t) {
    const TrajectoryRecord& x = a.table().records()[t];
    const TrajectoryRecord& y = b.table().records()[t];
    EXPECT_EQ(x.seqs, y.seqs);
    EXPECT_EQ(x.utimes, y.utimes);
    ASSERT_EQ(x.scans.size(), y.scans.size());
    for (size_t i = 0; i < x.scans.size(); ++i) EXPECT_EQ(x.scans[i].ranges, y.scans[i].ranges);
  }
  EXPECT_EQ(a.smoother().stats().variables, b.smoother().stats().variables);
  EXPECT_EQ(a.smoother().ActiveFactors().size(), b.smoother().ActiveFactors().size());
  EXPECT_EQ(a.num_anchored(), b.num_anchored());
}

class SnapshotCodecTest : public ::testing::Test {
 protected:
  void SetUp() override { SetMinLogLevel(LogLevel::kError); }
  void TearDown() override { SetMinLogLevel(LogLevel::kInfo); }
};

// A server restored from a snapshot taken at a random moment, fed the rest of the mission,
// ends with the uninterrupted server's map: the same keyframes, links, counters and acks,
// poses within 1e-9 after the final batch step.
TEST_F(SnapshotCodecTest, RestoredServerEndsWithTheUninterruptedMap) {
  const std::vector<Delivery> mission = LossyMission(40.0, 11);
  MappingServer live(Options());
  for (const Delivery& d : mission) Apply(&live, d);
  live.Flush();
  ASSERT_EQ(live.table().num_keyframes(), 3 * 81);
  ASSERT_EQ(live.stats().encounters_added, 16);
  ASSERT_GT(live.rejects().count(ErrorCode::kDuplicateSequence), 0);  // the bus doubled some

  std::mt19937 rng(5);
  for (int trial = 0; trial < 6; ++trial) {
    const size_t cut = 1 + rng() % (mission.size() - 1);
    SCOPED_TRACE("snapshot after delivery " + std::to_string(cut) + " of " +
                 std::to_string(mission.size()));
    MappingServer first(Options());
    for (size_t i = 0; i < cut; ++i) Apply(&first, mission[i]);
    SnapshotNodeState node;
    node.position = {static_cast<int64_t>(cut), mission[cut - 1].clock, "ticks"};
    node.robots = {"R1", "R2"};
    node.trajectories = {{"R1", 77}, {"R2", 78}};
    const Result<std::vector<uint8_t>> bytes = SnapshotCodec::Encode(first, node);
    ASSERT_TRUE(bytes.ok()) << bytes.status().message();

    MappingServer restored(Options());
    SnapshotNodeState read;
    const Status decoded = SnapshotCodec::Decode(bytes->data(), bytes->size(), &restored, &read);
    ASSERT_TRUE(decoded.ok()) << decoded.message();
    // Left deferring, unsolved: one batch step solves it (after a journal's tail, online).
    EXPECT_TRUE(restored.deferring_updates());
    EXPECT_FALSE(restored.CanSnapshot());
    const UpdateResult solved = restored.EndDeferredUpdates();
    ASSERT_TRUE(solved.status.ok()) << solved.status.message();
    EXPECT_TRUE(solved.batch_step);
    EXPECT_EQ(read.position.events, node.position.events);
    EXPECT_EQ(read.position.last_utime, node.position.last_utime);
    EXPECT_EQ(read.position.last_channel, "ticks");
    EXPECT_EQ(read.robots, node.robots);
    EXPECT_EQ(read.trajectories, node.trajectories);
    ExpectSameState(first, restored);
    // Round trip: a snapshot of the restored server is the same bytes.
    const Result<std::vector<uint8_t>> again = SnapshotCodec::Encode(restored, read);
    ASSERT_TRUE(again.ok());
    EXPECT_TRUE(*again == *bytes);

    for (size_t i = cut; i < mission.size(); ++i) {
      Apply(&first, mission[i]);
      Apply(&restored, mission[i]);
    }
    first.Flush();
    restored.Flush();
    ExpectSameState(live, restored);
    EXPECT_LT(testing::LargestPoseDifference(live.BuildMergedMap(), restored.BuildMergedMap()),
              1e-9);
  }
}

class SnapshotRefusalTest : public SnapshotCodecTest {
 protected:
  void SetUp() override {
    SnapshotCodecTest::SetUp();
    const std::vector<Delivery> mission = LossyMission(10.0, 3);
    MappingServer server(Options());
    for (size_t i = 0; i < mission.size() / 2; ++i) Apply(&server, mission[i]);
    SnapshotNodeState node;
    node.position = {42, 123, "KEYFRAMES"};
    Result<std::vector<uint8_t>> encoded = SnapshotCodec::Encode(server, node);
    ASSERT_TRUE(encoded.ok());
    bytes_ = std::move(*encoded);
  }
  // Why a decode of `bytes` into a fresh server fails ("" if it does not).
  static std::string Refusal(const std::vector<uint8_t>& bytes) {
    MappingServer server(Options());
    SnapshotNodeState node;
    const Status status = SnapshotCodec::Decode(bytes.data(), bytes.size(), &server, &node);
    if (status.ok()) return "";
    EXPECT_EQ(status.code(), ErrorCode::kDecodeFailed);
    return status.message();
  }
  std::vector<uint8_t> bytes_;
};

TEST_F(SnapshotRefusalTest, AWholeSnapshotIsReadAndItsPositionFound) {
  EXPECT_EQ(Refusal(bytes_), "");
  const Result<JournalPosition> position =
      SnapshotCodec::ReadPosition(bytes_.data(), bytes_.size());
  ASSERT_TRUE(position.ok());
  EXPECT_EQ(position->events, 42);
  EXPECT_EQ(position->last_utime, 123);
  EXPECT_EQ(position->last_channel, "KEYFRAMES");
}

TEST_F(SnapshotRefusalTest, TruncatedSnapshotsAreRefused) {
  for (const size_t size : {size_t{0}, size_t{10}, bytes_.size() / 2, bytes_.size() - 1}) {
    const std::vector<uint8_t> cut(bytes_.begin(), bytes_.begin() + static_cast<long>(size));
    EXPECT_NE(Refusal(cut).find("truncated"), std::string::npos) << size;
    EXPECT_FALSE(SnapshotCodec::ReadPosition(cut.data(), cut.size()).ok());
  }
}

TEST_F(SnapshotRefusalTest, AnyFlippedByteIsRefused) {
  std::mt19937 rng(9);
  for (int trial = 0; trial < 20; ++trial) {
    std::vector<uint8_t> corrupt = bytes_;
    const size_t at = rng() % corrupt.size();
    corrupt[at] ^= static_cast<uint8_t>(1 + rng() % 255);
    const std::string why = Refusal(corrupt);
    EXPECT_FALSE(why.empty()) << "byte " << at;
    EXPECT_FALSE(SnapshotCodec::ReadPosition(corrupt.data(), corrupt.size()).ok()) << at;
  }
  std::vector<uint8_t> payload_flip = bytes_;
  payload_flip[payload_flip.size() / 2] ^= 0x10;
  EXPECT_NE(Refusal(payload_flip).find("checksum"), std::string::npos);
  std::vector<uint8_t> other_version = bytes_;
  other_version[8] = static_cast<uint8_t>(kSnapshotVersion + 1);
  EXPECT_NE(Refusal(other_version).find("version"), std::string::npos);
}

// The scan-matching sources' state is not in a snapshot: a server with one neither writes
// nor reads them.
TEST_F(SnapshotRefusalTest, ServersWithAScanMatchingSourceAreNotSnapshot) {
  MappingServerOptions options = Options();
  options.loop_closures = true;
  options.match_workers = 0;
  MappingServer server(options);
  EXPECT_FALSE(server.CanSnapshot());
  const Result<std::vector<uint8_t>> encoded = SnapshotCodec::Encode(server, {});
  ASSERT_FALSE(encoded.ok());
  EXPECT_EQ(encoded.status().code(), ErrorCode::kInvalidArgument);
  SnapshotNodeState node;
  const Status decoded = SnapshotCodec::Decode(bytes_.data(), bytes_.size(), &server, &node);
  EXPECT_FALSE(decoded.ok());
  EXPECT_EQ(decoded.code(), ErrorCode::kInvalidArgument);
}

}  // namespace
}  // namespace anchormap
