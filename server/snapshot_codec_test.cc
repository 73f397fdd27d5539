#include "server/snapshot_codec.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "common/util/log.h"
#include "server/byte_codec.h"
#include "server/smoother_state_codec.h"
#include "tests/scan_testing/scan_scenarios.h"
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
// With `relay_counts`, each keyframe carries its robot's count of relayed encounters.
std::vector<Delivery> LossyMission(double duration_s, uint32_t seed, bool relay_counts = false) {
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
      if (relay_counts) k.encounters_relayed = encounter_seq[r];
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

// The version-1 bytes of the same state: version 1 is version 2 without its last sections
// (the smoother's state, the pool's numbering, no scan source here), under its own
// envelope (magic, version, payload size, payload, FNV-1a 64).
std::vector<uint8_t> AsVersion1(const MappingServer& server, const SnapshotNodeState& node) {
  const Result<std::vector<uint8_t>> encoded = SnapshotCodec::EncodeVersion(server, node, 2);
  if (!encoded.ok()) {
    ADD_FAILURE() << encoded.status().message();
    return {};
  }
  const std::vector<uint8_t>& v2 = *encoded;
  ByteWriter tail;
  PutSmootherState(&tail, 2, server.smoother().ExportState());
  const size_t tail_size = tail.bytes().size() + 8 + 8;  // + next ordinal, sources (0)
  const size_t header = 8 + 4 + 8;
  const std::vector<uint8_t> payload(v2.begin() + header, v2.end() - 8 - tail_size);
  ByteWriter w;
  w.bytes().assign(v2.begin(), v2.begin() + 8);  // the magic
  w.Raw<uint32_t>(1);
  w.Raw<uint64_t>(payload.size());
  w.bytes().insert(w.bytes().end(), payload.begin(), payload.end());
  uint64_t hash = 0xcbf29ce484222325ULL;
  for (uint8_t b : w.bytes()) {
    hash ^= b;
    hash *= 0x100000001b3ULL;
  }
  w.Raw(hash);
  return w.Take();
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
// the same state to the bit (version 2: the smoother's state is in it); from the same
// snapshot in version 1 (no smoother state: one batch step), poses within 1e-9 after the
// final batch step.
TEST_F(SnapshotCodecTest, RestoredServerEndsWithTheUninterruptedMap) {
  const std::vector<Delivery> mission = LossyMission(40.0, 11);
  MappingServer live(Options());
  for (const Delivery& d : mission) Apply(&live, d);
  live.Flush();
  const Result<std::vector<uint8_t>> live_bytes = SnapshotCodec::Encode(live, {});
  ASSERT_TRUE(live_bytes.ok());
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
    // Version 2: solved, as the snapshot's server was.
    EXPECT_FALSE(restored.deferring_updates());
    EXPECT_TRUE(restored.CanSnapshot());
    // Version 1: left deferring, unsolved: one batch step solves it (after a journal's
    // tail, online).
    const std::vector<uint8_t> v1 = AsVersion1(first, node);
    MappingServer from_v1(Options());
    SnapshotNodeState read_v1;
    const Status decoded_v1 = SnapshotCodec::Decode(v1.data(), v1.size(), &from_v1, &read_v1);
    ASSERT_TRUE(decoded_v1.ok()) << decoded_v1.message();
    EXPECT_TRUE(from_v1.deferring_updates());
    EXPECT_FALSE(from_v1.CanSnapshot());
    const UpdateResult solved = from_v1.EndDeferredUpdates();
    ASSERT_TRUE(solved.status.ok()) << solved.status.message();
    EXPECT_TRUE(solved.batch_step);
    EXPECT_EQ(read_v1.robots, node.robots);
    ExpectSameState(first, from_v1);
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
      Apply(&from_v1, mission[i]);
    }
    first.Flush();
    restored.Flush();
    from_v1.Flush();
    ExpectSameState(live, restored);
    ExpectSameState(live, from_v1);
    const Result<std::vector<uint8_t>> restored_bytes = SnapshotCodec::Encode(restored, {});
    ASSERT_TRUE(restored_bytes.ok());
    EXPECT_TRUE(*restored_bytes == *live_bytes);  // every field, the smoother's state too
    EXPECT_EQ(testing::LargestPoseDifference(live.BuildMergedMap(), restored.BuildMergedMap()),
              0.0);
    EXPECT_LT(testing::LargestPoseDifference(live.BuildMergedMap(), from_v1.BuildMergedMap()),
              1e-9);
  }
}

// Version 3 holds the keyframes' counts of relayed encounters and what they revealed (the
// delivery windows, the order stage's encounter streams, the last admitted count): with
// every keyframe carrying its count, a server restored at a random moment of the lossy
// mission (lost encounters revealed by the next keyframe and held for) ends with the
// uninterrupted server's bytes. Version 2 bytes of the same state leave the counts out.
TEST_F(SnapshotCodecTest, RelayCountsAndWhatTheyRevealedAreHeld) {
  const std::vector<Delivery> mission = LossyMission(40.0, 11, /*relay_counts=*/true);
  MappingServer live(Options());
  for (const Delivery& d : mission) Apply(&live, d);
  live.Flush();
  EXPECT_EQ(live.order_stats().late, 0);
  EXPECT_EQ(live.rejects().count(ErrorCode::kBadSequence), 0);
  const Result<std::vector<uint8_t>> live_bytes = SnapshotCodec::Encode(live, {});
  ASSERT_TRUE(live_bytes.ok());
  std::mt19937 rng(7);
  for (int trial = 0; trial < 4; ++trial) {
    const size_t cut = 1 + rng() % (mission.size() - 1);
    SCOPED_TRACE("snapshot after delivery " + std::to_string(cut));
    MappingServer first(Options());
    for (size_t i = 0; i < cut; ++i) Apply(&first, mission[i]);
    const Result<std::vector<uint8_t>> bytes = SnapshotCodec::Encode(first, {});
    const Result<std::vector<uint8_t>> v2 = SnapshotCodec::EncodeVersion(first, {}, 2);
    ASSERT_TRUE(bytes.ok() && v2.ok());
    EXPECT_GT(bytes->size(), v2->size());  // the counts
    MappingServer restored(Options());
    SnapshotNodeState read;
    ASSERT_TRUE(SnapshotCodec::Decode(bytes->data(), bytes->size(), &restored, &read).ok());
    const Result<std::vector<uint8_t>> again = SnapshotCodec::Encode(restored, read);
    ASSERT_TRUE(again.ok());
    EXPECT_TRUE(*again == *bytes);
    for (size_t i = cut; i < mission.size(); ++i) Apply(&restored, mission[i]);
    restored.Flush();
    ExpectSameState(live, restored);
    const Result<std::vector<uint8_t>> end = SnapshotCodec::Encode(restored, {});
    ASSERT_TRUE(end.ok());
    EXPECT_TRUE(*end == *live_bytes);
  }
}

// The scan-matching sources on (loop closures and scan encounters, two workers): R1 and R2 lap the
// LoopWorld block from opposite corners, keyframes interleaved, each received 0.1 s after its time,
// a tick after each pair.
std::vector<Delivery> ScanMission() {
  const testing::SyntheticWorld world = testing::LoopWorld();
  const testing::OdometryNoise noise{0.01, 0.005};
  const std::vector<Keyframe> k1 =
      testing::DriveKeyframes(world, testing::LoopWorldLap(0, 115), "R1", 1, 1'000'000, noise, 1);
  const std::vector<Keyframe> k2 = testing::DriveKeyframes(world, testing::LoopWorldLap(50, 115),
                                                           "R2", 2, 1'000'000, noise, 101);
  std::vector<Delivery> out;
  for (size_t i = 0; i < k1.size(); ++i) {
    for (const Keyframe& k : {k1[i], k2[i]}) {
      Delivery d;
      d.kind = Delivery::Kind::kKeyframe;
      d.clock = k.utime + 100'000;
      d.keyframe = k;
      out.push_back(std::move(d));
    }
    Delivery tick;
    tick.clock = k1[i].utime + 200'000;
    out.push_back(tick);
  }
  Delivery settled;
  settled.clock = out.back().clock + 10'000'000;
  out.push_back(settled);
  return out;
}

MappingServerOptions ScanServerOptions() {
  MappingServerOptions options = Options();
  options.loop_closures = true;
  options.scan_encounters = true;
  options.match_workers = 2;
  // At lag 0 a match is used in the call that submits it: none is in flight between two
  // inputs. A lag leaves them in flight at a snapshot (the path under test); lag 0 is the
  // crash test's (the daemons' default).
  options.match_schedule.lag_s = 0.5;
  options.scan.first_join_hold_s = 5.0;  // no direct encounters to wait for
  return options;
}

// With the scan-matching sources on, a server restored from a snapshot taken at three
// moments (matches in flight, keyframes waiting, candidates kept) and fed the rest of the
// mission continues exactly as the uninterrupted one: the same closures and encounters
// (links, counters by kind, the sources' figures), and at the end the same state to the
// bit, the smoother's and the sources' included (its snapshot is the same bytes), hence the
// same map (0 difference, the brief's bound being 1e-9).
// (The body of the tests below, with one update per input or a solve period, and with
// matching budgets tight enough to skip keyframes.)
void ExpectARestoredServerToContinueExactly(double solve_period_s, bool tight_budgets = false) {
  const std::vector<Delivery> mission = ScanMission();
  MappingServerOptions options = ScanServerOptions();
  options.solve_period_s = solve_period_s;
  if (tight_budgets) {
    options.loop.budget = {2.0, 4.0};
    options.scan.near_budget = {1.0, 2.0};
  }
  MappingServer live(options);
  const size_t n = mission.size();
  // Matches in flight and candidates kept by the sources now.
  const auto work_in_progress = [&live](int* in_flight, int* kept) {
    for (const EncounterSource* source : live.sources()) {
      if (const auto* loop = dynamic_cast<const LoopClosures*>(source)) {
        const LoopClosureState state = loop->ExportState();
        *in_flight += static_cast<int>(state.matches.size());
        for (const auto& [trajectory, hypotheses] : state.kept) {
          *kept += static_cast<int>(hypotheses.size());
        }
      } else if (const auto* scan = dynamic_cast<const ScanEncounters*>(source)) {
        const ScanEncounterState state = scan->ExportState();
        *in_flight += static_cast<int>(state.matches.size());
        for (const auto& [pair, candidates] : state.kept) {
          *kept += static_cast<int>(candidates.size());
        }
      }
    }
  };
  // Snapshots: after a third of the mission, then at the first moments after half and after
  // four fifths at which matches are in flight.
  std::vector<size_t> cuts;
  std::vector<std::vector<uint8_t>> snapshots;
  int in_flight_at_cuts = 0, kept_at_cuts = 0;
  for (size_t i = 0; i < n; ++i) {
    Apply(&live, mission[i]);
    const size_t applied = i + 1;
    int in_flight = 0, kept = 0;
    if (applied == n / 3 || (applied >= n / 2 && cuts.size() == 1) ||
        (applied >= 4 * n / 5 && cuts.size() == 2)) {
      work_in_progress(&in_flight, &kept);
      if (applied != n / 3 && in_flight == 0) continue;
    } else {
      continue;
    }
    ASSERT_TRUE(live.CanSnapshot());
    SnapshotNodeState node;
    node.position = {static_cast<int64_t>(applied), mission[i].clock, "ticks"};
    Result<std::vector<uint8_t>> bytes = SnapshotCodec::Encode(live, node);
    ASSERT_TRUE(bytes.ok()) << bytes.status().message();
    cuts.push_back(applied);
    snapshots.push_back(std::move(*bytes));
    in_flight_at_cuts += in_flight;
    kept_at_cuts += kept;
  }
  live.Flush();
  const Result<std::vector<uint8_t>> live_bytes = SnapshotCodec::Encode(live, {});
  ASSERT_TRUE(live_bytes.ok());
  // The scenario exercises both sources, and the snapshots hold their work in progress.
  const auto& by_kind = live.stats().added_by_kind;
  EXPECT_GT(by_kind[static_cast<int>(ConstraintKind::kLoopClosure)], 0);
  EXPECT_GT(by_kind[static_cast<int>(ConstraintKind::kScanEncounter)], 0);
  ASSERT_EQ(cuts.size(), 3u);
  EXPECT_GT(in_flight_at_cuts, 0);
  EXPECT_GT(kept_at_cuts, 0);

  for (size_t c = 0; c < cuts.size(); ++c) {
    SCOPED_TRACE("snapshot after delivery " + std::to_string(cuts[c]) + " of " + std::to_string(n));
    MappingServer restored(options);
    SnapshotNodeState read;
    const Status decoded =
        SnapshotCodec::Decode(snapshots[c].data(), snapshots[c].size(), &restored, &read);
    ASSERT_TRUE(decoded.ok()) << decoded.message();
    EXPECT_FALSE(restored.deferring_updates());
    // Round trip: the restored server's snapshot is the same bytes.
    const Result<std::vector<uint8_t>> again = SnapshotCodec::Encode(restored, read);
    ASSERT_TRUE(again.ok());
    EXPECT_TRUE(*again == snapshots[c]);
    for (size_t i = cuts[c]; i < n; ++i) Apply(&restored, mission[i]);
    restored.Flush();
    EXPECT_EQ(live.encounter_links(), restored.encounter_links());
    EXPECT_EQ(live.stats().added_by_kind, restored.stats().added_by_kind);
    EXPECT_EQ(live.stats().updates, restored.stats().updates);
    EXPECT_EQ(live.smoother().stats().batch_steps, restored.smoother().stats().batch_steps);
    const Result<std::vector<uint8_t>> end = SnapshotCodec::Encode(restored, {});
    ASSERT_TRUE(end.ok());
    EXPECT_TRUE(*end == *live_bytes);  // every field: graph, smoother, sources, counters
    EXPECT_EQ(testing::LargestPoseDifference(live.BuildMergedMap(), restored.BuildMergedMap()),
              0.0);
  }
  if (solve_period_s > 0) {
    EXPECT_GT(live.stats().inputs_batched, 0);
  }
  if (tight_budgets) {  // the budgets bound: keyframes were left unexamined
    for (const EncounterSource* source : live.sources()) {
      if (const auto* loop = dynamic_cast<const LoopClosures*>(source)) {
        EXPECT_GT(loop->budget().skipped(), 0);
      } else if (const auto* scan = dynamic_cast<const ScanEncounters*>(source)) {
        EXPECT_GT(scan->near_budget().skipped(), 0);
      }
    }
  }
}

TEST_F(SnapshotCodecTest, WithTheScanSourcesOnARestoredServerContinuesExactly) {
  ExpectARestoredServerToContinueExactly(0.0);
}

// With a solve period a snapshot falls between updates as often as not: it holds the inputs
// pending and the period's start (version 4), so the restored server solves when the
// uninterrupted one does and reaches the same state to the bit.
TEST_F(SnapshotCodecTest, WithASolvePeriodARestoredServerContinuesExactly) {
  ExpectARestoredServerToContinueExactly(1.0);
}

// Budgets that bind (version 9 holds their tokens and each trajectory's ledger): the restored
// server serves the keyframes the uninterrupted one serves.
TEST_F(SnapshotCodecTest, WithBindingMatchBudgetsARestoredServerContinuesExactly) {
  ExpectARestoredServerToContinueExactly(1.0, /*tight_budgets=*/true);
}

class SnapshotRefusalTest : public SnapshotCodecTest {
 protected:
  void SetUp() override {
    SnapshotCodecTest::SetUp();
    const std::vector<Delivery> mission = LossyMission(10.0, 3);
    MappingServer& server = server_at_snapshot_;
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
  MappingServer server_at_snapshot_{Options()};
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

// A source added from outside (AddEncounterSource) has no state in a snapshot: such a
// server is not snapshot.
TEST_F(SnapshotRefusalTest, AServerWithAnAddedSourceIsNotSnapshot) {
  MappingServer server(Options());
  server.AddEncounterSource(std::make_unique<DirectEncounters>());
  EXPECT_FALSE(server.CanSnapshot());
  const Result<std::vector<uint8_t>> encoded = SnapshotCodec::Encode(server, {});
  ASSERT_FALSE(encoded.ok());
  EXPECT_EQ(encoded.status().code(), ErrorCode::kInvalidArgument);
}

// A snapshot restores a server with the same sources only: another set is refused.
TEST_F(SnapshotRefusalTest, ASnapshotOfOtherSourcesIsRefused) {
  MappingServerOptions options = Options();
  options.loop_closures = true;
  options.match_workers = 0;
  MappingServer server(options);
  EXPECT_TRUE(server.CanSnapshot());
  SnapshotNodeState node;
  const Status decoded = SnapshotCodec::Decode(bytes_.data(), bytes_.size(), &server, &node);
  EXPECT_EQ(decoded.code(), ErrorCode::kDecodeFailed);
  EXPECT_NE(decoded.message().find("another set of sources"), std::string::npos);
  // A version-1 snapshot held no scan-matching source.
  MappingServer direct(Options());
  const std::vector<uint8_t> v1 = AsVersion1(server_at_snapshot_, SnapshotNodeState{});
  MappingServer other(options);
  const Status old = SnapshotCodec::Decode(v1.data(), v1.size(), &other, &node);
  EXPECT_EQ(old.code(), ErrorCode::kInvalidArgument);
  EXPECT_TRUE(SnapshotCodec::Decode(v1.data(), v1.size(), &direct, &node).ok());
  // Nor into a server with the reduced graph: a version-1 snapshot restores by deferring
  // updates, which the fold does not allow (later versions load: reduced_graph_test.cc).
  MappingServerOptions reduced = Options();
  reduced.reduced_graph.enabled = true;
  MappingServer folding(reduced);
  const Status deferred = SnapshotCodec::Decode(v1.data(), v1.size(), &folding, &node);
  EXPECT_EQ(deferred.code(), ErrorCode::kInvalidArgument);
  EXPECT_NE(deferred.message().find("reduced graph"), std::string::npos) << deferred.message();
  MappingServer folding_v12(reduced);
  EXPECT_TRUE(SnapshotCodec::Decode(bytes_.data(), bytes_.size(), &folding_v12, &node).ok());
  EXPECT_EQ(folding_v12.folder()->num_nodes(),
            static_cast<size_t>(server_at_snapshot_.table().num_keyframes()));
}

}  // namespace
}  // namespace anchormap
