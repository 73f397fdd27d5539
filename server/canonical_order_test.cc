#include "server/canonical_order.h"

#include <algorithm>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "server/mapping_server.h"
#include "tests/scan_testing/scan_scenarios.h"

namespace anchormap {
namespace {

Keyframe MakeKeyframe(const std::string& robot, int64_t trajectory_id, int32_t seq, int64_t utime) {
  Keyframe k;
  k.robot = robot;
  k.trajectory_id = trajectory_id;
  k.seq = seq;
  k.utime = utime;
  return k;
}

Encounter MakeEncounter(const std::string& observer, const std::string& observed, int64_t utime) {
  Encounter e;
  e.observer = observer;
  e.observed = observed;
  e.utime = utime;
  return e;
}

// Everything the stage releases at `now` (no settling), as "R1:3" / "E:R1>R2" labels.
std::vector<std::string> Drain(CanonicalInputOrder* order, int64_t now) {
  std::vector<std::string> out;
  while (auto input = order->Next(now, /*settle=*/false)) {
    out.push_back(input->is_keyframe
                      ? input->keyframe.robot + ":" + std::to_string(input->keyframe.seq)
                      : "E:" + input->encounter.observer + ">" + input->encounter.observed);
  }
  return out;
}

using Labels = std::vector<std::string>;

TEST(CanonicalInputOrderTest, HoldsUntilEveryTrajectoryHasPassedThatTime) {
  CanonicalInputOrder order;
  const TrajectoryId r1(0), r2(1);
  order.AddKeyframe(r1, MakeKeyframe("R1", 1, 0, 1'000'000), 0);
  // R2 unknown: nothing holds R1.
  EXPECT_EQ(Drain(&order, 0), (Labels{"R1:0"}));
  order.AddKeyframe(r2, MakeKeyframe("R2", 2, 0, 1'100'000), 0);
  EXPECT_EQ(Drain(&order, 0), (Labels{}));  // R1 has not passed 1.1 s yet
  order.AddKeyframe(r1, MakeKeyframe("R1", 1, 1, 2'000'000), 0);
  order.AddEncounter(MakeEncounter("R2", "R1", 1'500'000), 0);
  order.AddKeyframe(r1, MakeKeyframe("R1", 1, 2, 3'000'000), 0);
  // R2's 1.1 s goes; the encounter at 1.5 s waits for R2 to pass 1.5 s.
  EXPECT_EQ(Drain(&order, 0), (Labels{"R2:0"}));
  order.AddKeyframe(r2, MakeKeyframe("R2", 2, 1, 2'000'000), 0);
  // At 2.0 s both: keyframes before encounters, then robot order.
  EXPECT_EQ(Drain(&order, 0), (Labels{"E:R2>R1", "R1:1", "R2:1"}));
  EXPECT_EQ(order.held(), 1u);
  EXPECT_EQ(order.stats().late, 0);
  EXPECT_EQ(order.NextAtEnd()->keyframe.seq, 2);
  EXPECT_FALSE(order.NextAtEnd());
}

TEST(CanonicalInputOrderTest, ASilentTrajectoryStopsHoldingAfterThePatience) {
  CanonicalOrderOptions options;
  options.patience_s = 5.0;
  CanonicalInputOrder order(options);
  const TrajectoryId r1(0), r2(1);
  order.AddKeyframe(r1, MakeKeyframe("R1", 1, 0, 1'000'000), 0);
  order.AddKeyframe(r2, MakeKeyframe("R2", 2, 0, 1'000'000), 0);
  order.AddKeyframe(r1, MakeKeyframe("R1", 1, 1, 2'000'000), 1'000'000);
  EXPECT_EQ(Drain(&order, 1'000'000), (Labels{"R1:0", "R2:0"}));
  std::vector<TrajectoryId> silenced;
  EXPECT_FALSE(order.Next(5'000'000, false, &silenced));  // R2 heard 5 s ago: still holds
  EXPECT_TRUE(silenced.empty());
  auto input = order.Next(5'000'001, false, &silenced);
  ASSERT_TRUE(input);
  EXPECT_EQ(input->keyframe.seq, 1);
  EXPECT_EQ(silenced, std::vector<TrajectoryId>{r2});
  EXPECT_EQ(order.stats().silences, 1);
  // R2 speaks again with an old time: released at once, counted late.
  order.AddKeyframe(r2, MakeKeyframe("R2", 2, 1, 1'500'000), 6'000'000);
  EXPECT_EQ(Drain(&order, 6'000'000), (Labels{"R2:1"}));
  EXPECT_EQ(order.stats().late, 1);
}

TEST(CanonicalInputOrderTest, AGapInAnEncounterSequenceHoldsWhatComesAfterItsLastTime) {
  CanonicalInputOrder order;
  const TrajectoryId r1(0);
  Encounter e = MakeEncounter("R1", "R2", 1'000'000);
  e.observer_trajectory_id = 1;
  e.seq = 0;
  order.AddEncounter(e, 0);
  e.seq = 2;  // seq 1 (between 1 s and 3 s) is missing
  e.utime = 3'000'000;
  order.AddEncounter(e, 0);
  for (int32_t seq = 0; seq < 4; ++seq) {
    order.AddKeyframe(r1, MakeKeyframe("R1", 1, seq, 1'000'000 * (seq + 1)), 0);
  }
  EXPECT_EQ(Drain(&order, 0), (Labels{"R1:0", "E:R1>R2"}));
  e.seq = 1;
  e.utime = 1'500'000;
  order.AddEncounter(e, 0);
  EXPECT_EQ(Drain(&order, 0), (Labels{"E:R1>R2", "R1:1", "R1:2", "E:R1>R2", "R1:3"}));
  EXPECT_EQ(order.stats().late, 0);
}

// An encounter lost with no later one of its observer: the observer's next keyframe carries
// the count of encounters relayed before it, which reveals the gap. Inputs after the last
// contiguous encounter's time wait for the resend (without the count, R1:2 and R1:3 went
// out first and the resent encounter was late).
TEST(CanonicalInputOrderTest, AKeyframesRelayCountRevealsALostLastEncounter) {
  for (const bool revealed : {false, true}) {
    CanonicalInputOrder order;
    const TrajectoryId r1(0);
    Encounter e = MakeEncounter("R1", "R2", 1'000'000);
    e.observer_trajectory_id = 1;
    e.seq = 0;
    order.AddEncounter(e, 0);
    // Seq 1 at 1.5 s is lost; keyframes 1 .. 3 were published after it was relayed.
    for (int32_t seq = 0; seq < 4; ++seq) {
      order.AddKeyframe(r1, MakeKeyframe("R1", 1, seq, 1'000'000 * (seq + 1)), 0);
      if (seq == 1 && revealed) order.ExpectEncounters("R1", 1, 2, 0);
    }
    EXPECT_EQ(Drain(&order, 0), revealed ? (Labels{"R1:0", "E:R1>R2"})
                                         : (Labels{"R1:0", "E:R1>R2", "R1:1", "R1:2", "R1:3"}));
    e.seq = 1;
    e.utime = 1'500'000;
    order.AddEncounter(e, 0);
    EXPECT_EQ(Drain(&order, 0),
              revealed ? (Labels{"E:R1>R2", "R1:1", "R1:2", "R1:3"}) : (Labels{"E:R1>R2"}));
    EXPECT_EQ(order.stats().late, revealed ? 0 : 1);
  }
  // The gap holds for patience_s at most, like a gap between two arrived encounters.
  CanonicalOrderOptions options;
  options.patience_s = 5.0;
  CanonicalInputOrder order(options);
  order.AddKeyframe(TrajectoryId(0), MakeKeyframe("R1", 1, 0, 1'000'000), 0);
  order.AddKeyframe(TrajectoryId(0), MakeKeyframe("R1", 1, 1, 2'000'000), 0);
  order.ExpectEncounters("R1", 1, 1, 0);  // seq 0, time unknown: all that waits waits
  EXPECT_EQ(Drain(&order, 5'000'000), Labels{});
  EXPECT_EQ(Drain(&order, 5'000'001), (Labels{"R1:0", "R1:1"}));
}

TEST(CanonicalInputOrderTest, OnlineAnInputWaitsTheSettleTime) {
  CanonicalOrderOptions options;
  options.settle_s = 2.0;
  CanonicalInputOrder order(options);
  order.AddKeyframe(TrajectoryId(0), MakeKeyframe("R1", 1, 0, 1'000'000), 10'000'000);
  EXPECT_FALSE(order.Next(11'999'999, /*settle=*/true));
  EXPECT_TRUE(order.Next(12'000'000, /*settle=*/true));
}

// After a restart what waits settles again from the restart: an encounter lost while the
// server was down and resent within settle_s of the restart goes out before the keyframes
// after it, although they had settled long before (they came before the crash).
TEST(CanonicalInputOrderTest, ARestartSettlesWhatWaitsAgain) {
  CanonicalOrderOptions options;
  options.settle_s = 2.0;
  CanonicalInputOrder order(options);
  order.AddKeyframe(TrajectoryId(0), MakeKeyframe("R1", 1, 0, 1'000'000), 10'000'000);
  order.AddKeyframe(TrajectoryId(0), MakeKeyframe("R1", 1, 1, 3'000'000), 10'000'000);
  order.ResumeAt(30'000'000);
  EXPECT_FALSE(order.Next(31'000'000, /*settle=*/true));
  order.AddEncounter(MakeEncounter("R1", "R2", 2'000'000), 31'500'000);  // the resend
  std::vector<std::string> out;
  for (int64_t now = 31'000'000; now <= 34'000'000; now += 100'000) {
    while (auto input = order.Next(now, /*settle=*/true)) {
      out.push_back(input->is_keyframe ? "R1:" + std::to_string(input->keyframe.seq) : "E");
    }
  }
  EXPECT_EQ(out, (Labels{"R1:0", "E", "R1:1"}));
  EXPECT_EQ(order.stats().late, 0);
}

// The two-robot loop world with the scan sources on (the defaults) and one direct
// encounter: what the graph holds after Flush.
struct MapResult {
  std::vector<Pose2> poses;  // every keyframe, global frame, trajectory by trajectory
  std::vector<EncounterLink> links;
  int64_t late = 0;
  int64_t loop_closures = 0;
  int64_t scan_encounters = 0;
  int64_t bridged = 0;
};

struct Inputs {
  std::vector<Keyframe> r1, r2;
  Encounter encounter;
};

const Inputs& TwoRobotInputs() {
  static const Inputs inputs = [] {
    const testing::SyntheticWorld world = testing::LoopWorld();
    const std::vector<Pose2> path1 = testing::LoopWorldLap(0, 70),
                             path2 = testing::LoopWorldLap(50, 70);
    Inputs in;
    in.r1 = testing::DriveKeyframes(world, path1, "R1", 1, 1'000'000,
                                    testing::OdometryNoise{0.01, 0.005}, 3);
    in.r2 = testing::DriveKeyframes(world, path2, "R2", 2, 1'000'000,
                                    testing::OdometryNoise{0.01, 0.005}, 103);
    // R1 sees R2 at its keyframe 30 (true relative pose, 5 cm noise level).
    in.encounter.utime = in.r1[30].utime;
    in.encounter.observer = "R1";
    in.encounter.observer_trajectory_id = 1;
    in.encounter.observed = "R2";
    in.encounter.T_observer_observed = Between(path1[30], path2[30]);
    in.encounter.covariance = Eigen::Vector3d(0.0025, 0.0025, 0.0004).asDiagonal();
    in.encounter.seq = 0;
    return in;
  }();
  return inputs;
}

MapResult RunInOrder(const std::vector<OrderedInput>& inputs, int workers = 2) {
  MappingServerOptions options;
  options.loop_closures = true;
  options.scan_encounters = true;
  options.match_workers = workers;
  MappingServer server(options);
  for (const OrderedInput& input : inputs) {
    if (input.is_keyframe) {
      (void)server.OnKeyframe(input.keyframe);
    } else {
      (void)server.OnEncounter(input.encounter);
    }
  }
  server.Flush();
  MapResult result;
  for (const TrajectoryRecord& record : server.table().records()) {
    for (const Pose2& pose : server.smoother().GlobalTrajectory(record.solver_id)) {
      result.poses.push_back(pose);
    }
  }
  result.links = server.encounter_links();
  result.late = server.order_stats().late;
  result.loop_closures =
      server.stats().added_by_kind[static_cast<int>(ConstraintKind::kLoopClosure)];
  result.scan_encounters =
      server.stats().added_by_kind[static_cast<int>(ConstraintKind::kScanEncounter)];
  result.bridged = server.receipt().num_bridged_gaps();
  return result;
}

OrderedInput AsInput(const Keyframe& k) {
  OrderedInput input;
  input.keyframe = k;
  return input;
}

OrderedInput AsInput(const Encounter& e) {
  OrderedInput input;
  input.is_keyframe = false;
  input.encounter = e;
  return input;
}

void ExpectSameMap(const MapResult& a, const MapResult& b) {
  ASSERT_EQ(a.poses.size(), b.poses.size());
  for (size_t i = 0; i < a.poses.size(); ++i) {
    EXPECT_NEAR(a.poses[i].x(), b.poses[i].x(), 1e-9) << i;
    EXPECT_NEAR(a.poses[i].y(), b.poses[i].y(), 1e-9) << i;
    EXPECT_NEAR(a.poses[i].theta(), b.poses[i].theta(), 1e-9) << i;
  }
  ASSERT_EQ(a.links.size(), b.links.size());
  for (size_t i = 0; i < a.links.size(); ++i) {
    EXPECT_EQ(a.links[i].robot_a, b.links[i].robot_a) << i;
    EXPECT_EQ(a.links[i].index_a, b.links[i].index_a) << i;
    EXPECT_EQ(a.links[i].robot_b, b.links[i].robot_b) << i;
    EXPECT_EQ(a.links[i].index_b, b.links[i].index_b) << i;
    EXPECT_EQ(a.links[i].kind, b.links[i].kind) << i;
  }
}

TEST(CanonicalOrderServerTest, TwoInterleavingsOfOneInputSetGiveOneMap) {
  const Inputs& in = TwoRobotInputs();
  // Interleaving A: in time, R1 before R2, the encounter right after R1's keyframe.
  std::vector<OrderedInput> a;
  for (size_t i = 0; i < in.r1.size(); ++i) {
    a.push_back(AsInput(in.r1[i]));
    if (i == 30) a.push_back(AsInput(in.encounter));
    a.push_back(AsInput(in.r2[i]));
  }
  // Interleaving B: both first keyframes first (the stage must know both trajectories
  // before it releases anything: a trajectory it does not know of holds nothing, and
  // the first one released takes the first solver id), then R2 running up to 8 keyframes ahead of
  // R1 and back, neighbours swapped inside each trajectory (the delivery table restores their
  // order), some keyframes and the encounter sent twice. (An encounter that comes after both
  // robots' keyframes of its time were released is late: the stage cannot wait for
  // what it does not know of; see ARCHITECTURE.md.)
  std::vector<OrderedInput> b = {AsInput(in.r1[0]), AsInput(in.r2[0])};
  std::mt19937 rng(11);
  std::vector<Keyframe> r1(in.r1.begin() + 1, in.r1.end()), r2(in.r2.begin() + 1, in.r2.end());
  for (std::vector<Keyframe>* stream : {&r1, &r2}) {
    for (size_t i = 0; i + 1 < stream->size(); i += 3) std::swap((*stream)[i], (*stream)[i + 1]);
  }
  size_t i1 = 0, i2 = 0;
  while (i1 < r1.size() || i2 < r2.size()) {
    const bool r2_turn = i2 < r2.size() && (i1 >= r1.size() || (rng() % 3 != 0 && i2 < i1 + 8));
    const Keyframe& k = r2_turn ? r2[i2++] : r1[i1++];
    b.push_back(AsInput(k));
    if (rng() % 10 == 0) b.push_back(AsInput(k));  // a duplicate
    if (!r2_turn && k.seq == 30) {
      b.push_back(AsInput(in.encounter));
      b.push_back(AsInput(in.encounter));
    }
  }
  const MapResult first = RunInOrder(a);
  const MapResult second = RunInOrder(b);
  std::printf("A: %zu poses, %zu links (%lld loop closures, %lld scan encounters), late %lld\n",
              first.poses.size(), first.links.size(), static_cast<long long>(first.loop_closures),
              static_cast<long long>(first.scan_encounters), static_cast<long long>(first.late));
  std::printf("B: %zu poses, %zu links (%lld loop closures, %lld scan encounters), late %lld\n",
              second.poses.size(), second.links.size(),
              static_cast<long long>(second.loop_closures),
              static_cast<long long>(second.scan_encounters), static_cast<long long>(second.late));
  // The scan sources did something, so that the comparison means something.
  EXPECT_GT(first.loop_closures + first.scan_encounters, 0);
  EXPECT_EQ(first.late, 0);
  EXPECT_EQ(second.late, 0);
  EXPECT_EQ(second.bridged, 0);
  ExpectSameMap(first, second);
}

TEST(CanonicalOrderServerTest, TheMapDoesNotDependOnTheNumberOfMatchWorkers) {
  const Inputs& in = TwoRobotInputs();
  std::vector<OrderedInput> inputs;
  for (size_t i = 0; i < in.r1.size(); ++i) {
    inputs.push_back(AsInput(in.r1[i]));
    if (i == 30) inputs.push_back(AsInput(in.encounter));
    inputs.push_back(AsInput(in.r2[i]));
  }
  const MapResult one = RunInOrder(inputs, 1);
  const MapResult two = RunInOrder(inputs, 2);
  EXPECT_GT(one.scan_encounters, 0);
  ASSERT_EQ(one.poses.size(), two.poses.size());
  // Bit for bit: the same matches, used at the same points of the input.
  for (size_t i = 0; i < one.poses.size(); ++i) {
    EXPECT_EQ(one.poses[i].vector(), two.poses[i].vector()) << i;
  }
  ExpectSameMap(one, two);
}

}  // namespace
}  // namespace anchormap
