#include "server/node/server_node.h"

#include <algorithm>
#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "anchormap/keyframe_v1_t.hpp"
#include "common/bus/codec.h"
#include "common/bus/map_codec.h"
#include "common/bus/merged_map_assembler.h"
#include "tests/testing/straight_keyframes.h"

namespace anchormap {
namespace {

Keyframe MakeKeyframe(const std::string& robot, int64_t trajectory, int32_t seq) {
  return testing::StraightKeyframe(robot, trajectory, seq, /*num_rays=*/3);
}

// R1 (trajectory 11) sees R2 3 m to its left at t = 2 s.
Encounter R1SeesR2() {
  Encounter e;
  e.utime = 2'000'000;
  e.observer = "R1";
  e.observer_trajectory_id = 11;
  e.observed = "R2";
  e.T_observer_observed = Pose2(0.0, 3.0, 0.0);
  e.covariance = Eigen::Vector3d(1e-2, 1e-2, 1e-3).asDiagonal();
  return e;
}

class ServerNodeTest : public ::testing::Test {
 protected:
  ServerNodeTest()
      : node_(ServerOptions{}, [this](const std::string& channel, const std::vector<uint8_t>& b) {
          published_[channel].push_back(b);
        }) {}

  bool Send(const std::string& channel, const std::vector<uint8_t>& bytes) {
    return node_.OnMessage(channel, bytes.data(), bytes.size());
  }

  ServerNode node_;
  std::map<std::string, std::vector<std::vector<uint8_t>>> published_;
};

TEST_F(ServerNodeTest, DecodedKeyframesAndEncountersReachTheMapThatIsPublished) {
  for (int32_t seq = 0; seq < 3; ++seq) {
    EXPECT_TRUE(Send(channels::kKeyframes, EncodeKeyframe(MakeKeyframe("R1", 11, seq))));
    EXPECT_TRUE(Send(channels::kKeyframes, EncodeKeyframe(MakeKeyframe("R2", 12, seq))));
  }
  Encounter e = R1SeesR2();
  EXPECT_TRUE(Send(channels::kEncounters, EncodeEncounter(e)));
  node_.PublishAll();

  // The map as a header and chunks (R1 and R2: one chunk each) that assemble to it.
  ASSERT_EQ(published_[channels::kMapHeader].size(), 1u);
  ASSERT_EQ(published_[channels::kMapChunks].size(), 2u);
  MergedMapAssembler assembler;
  for (const auto& channel : {channels::kMapChunks, channels::kMapHeader}) {
    for (const auto& bytes : published_[channel]) {
      ASSERT_TRUE(assembler.Accept(channel, bytes.data(), bytes.size()).ok());
    }
  }
  const std::optional<MergedMap>& map = assembler.map();
  ASSERT_TRUE(map);
  ASSERT_EQ(map->trajectories.size(), 2u);
  EXPECT_EQ(map->trajectories[1].robot, "R2");
  EXPECT_EQ(map->trajectories[1].poses.size(), 3u);
  EXPECT_TRUE(map->trajectories[1].anchored);
  ASSERT_EQ(map->encounters.size(), 1u);
  // R2's pose 1 stands 3 m to the left of R1's pose 1.
  EXPECT_NEAR(map->trajectories[1].poses[1].y(), 3.0, 1e-6);

  const auto& covariance_bytes = published_[channels::kAnchorCovariances].at(0);
  const Result<AnchorCovariances> covariances =
      DecodeAnchorCovariances(covariance_bytes.data(), covariance_bytes.size());
  ASSERT_TRUE(covariances.ok());
  EXPECT_EQ(covariances->anchors.size(), 2u);
  EXPECT_FALSE(published_[channels::kGridTiles].empty());

  const auto& status_bytes = published_[channels::kServerStatus].at(0);
  const Result<ServerStatus> status = DecodeServerStatus(status_bytes.data(), status_bytes.size());
  ASSERT_TRUE(status.ok());
  EXPECT_EQ(status->keyframes, 6);
  EXPECT_EQ(status->num_anchored, 2);
}

// The number of anchors in an anchor covariances message (0 when it does not decode).
size_t AnchorsIn(const std::vector<uint8_t>& bytes) {
  const Result<AnchorCovariances> decoded = DecodeAnchorCovariances(bytes.data(), bytes.size());
  return decoded.ok() ? decoded->anchors.size() : 0;
}

TEST_F(ServerNodeTest, AnchorCovariancesGoAtTheirOwnPeriodAtOnceForANewAnchorAndWithFullMaps) {
  // The defaults: a map at most every 0.5 s after an update, the covariances every 2 s.
  ASSERT_EQ(node_.server().publisher().options().map_period_s, 0.5);
  ASSERT_EQ(node_.server().publisher().options().anchor_covariances_period_s, 2.0);
  const auto& maps = published_[channels::kMapHeader];
  const auto& covariances = published_[channels::kAnchorCovariances];
  std::vector<int> with_covariances;  // the maps (1-based) that carried covariances
  for (int32_t seq = 0; seq < 10; ++seq) {
    Send(channels::kKeyframes, EncodeKeyframe(MakeKeyframe("R1", 11, seq)));
    Send(channels::kKeyframes, EncodeKeyframe(MakeKeyframe("R2", 12, seq)));
    const size_t before = covariances.size();
    node_.PublishDue(500'000 * (seq + 1));
    ASSERT_EQ(maps.size(), static_cast<size_t>(seq + 1));  // every update's map
    if (covariances.size() > before) with_covariances.push_back(seq + 1);
  }
  // The first map, then 2 s apart: at 0.5, 2.5 and 4.5 s (no anchor yet).
  EXPECT_EQ(with_covariances, (std::vector<int>{1, 5, 9}));
  EXPECT_EQ(AnchorsIn(covariances.back()), 0u);

  // An encounter anchors both: the next map carries the two anchors, 1 s after the last.
  Encounter encounter = R1SeesR2();
  encounter.utime = 10'000'000;  // R1's and R2's keyframes 9
  Send(channels::kEncounters, EncodeEncounter(encounter));
  node_.PublishDue(5'500'000);
  ASSERT_EQ(maps.size(), 11u);
  ASSERT_EQ(covariances.size(), 4u);
  EXPECT_EQ(AnchorsIn(covariances.back()), 2u);
  // The same anchors, 0.5 s later: the map alone.
  Send(channels::kKeyframes, EncodeKeyframe(MakeKeyframe("R1", 11, 10)));
  Send(channels::kKeyframes, EncodeKeyframe(MakeKeyframe("R2", 12, 10)));
  node_.PublishDue(6'000'000);
  ASSERT_EQ(maps.size(), 12u);
  EXPECT_EQ(covariances.size(), 4u);
  // A full map (the end of input) carries them whatever the period.
  node_.PublishAll();
  EXPECT_EQ(maps.size(), 13u);
  ASSERT_EQ(covariances.size(), 5u);
  EXPECT_EQ(AnchorsIn(covariances.back()), 2u);

  // A period of 0: with every map.
  ServerOptions every_map;
  every_map.server.publish.anchor_covariances_period_s = 0.0;
  std::map<std::string, int> counts;
  ServerNode node(every_map, [&](const std::string& channel, const std::vector<uint8_t>&) {
    ++counts[channel];
  });
  for (int32_t seq = 0; seq < 4; ++seq) {
    const std::vector<uint8_t> bytes = EncodeKeyframe(MakeKeyframe("R1", 11, seq));
    node.OnMessage(channels::kKeyframes, bytes.data(), bytes.size());
    node.PublishDue(500'000 * (seq + 1));
  }
  EXPECT_EQ(counts[channels::kMapHeader], 4);
  EXPECT_EQ(counts[channels::kAnchorCovariances], 4);
}

TEST_F(ServerNodeTest, UndecodableBytesAreCountedByReasonOnTheirChannel) {
  const std::vector<uint8_t> garbage = {1, 2, 3};
  EXPECT_TRUE(Send(channels::kKeyframes, garbage));
  Keyframe bad = MakeKeyframe("R1", 11, 1);
  bad.T_previous_this_covariance(0, 0) = -1.0;
  EXPECT_TRUE(Send(channels::kKeyframes, EncodeKeyframe(bad)));
  EXPECT_TRUE(Send(channels::kEncounters, garbage));
  EXPECT_FALSE(Send("SOMEONE_ELSES_CHANNEL", garbage));  // not ours: ignored, not counted
  const RejectCounter& rejects = node_.server().rejects();
  EXPECT_EQ(rejects.count(ErrorCode::kDecodeFailed), 2);
  EXPECT_EQ(rejects.count(ErrorCode::kCovarianceNotSpd), 1);
  EXPECT_EQ(rejects.total(), 3);
  EXPECT_EQ(node_.server().stats().keyframes_received, 0);
}

// The inputs of a live session, journaled as the online main does (the logic's clock set to
// the receive time before each message, timer ticks in between).
class ServerNodeJournalTest : public ServerNodeTest {
 protected:
  ServerNodeJournalTest() {
    node_.SetJournal([this, append = AppendToMemory(&journal_)](const std::string& channel,
                                                                int64_t clock_utime,
                                                                const uint8_t* data, size_t size) {
      if (fail_appends_) return Status::Error(ErrorCode::kIoError, "disk full");
      return append(channel, clock_utime, data, size);
    });
  }
  // A message received at `clock_s` (seconds of the logic's clock).
  void Receive(double clock_s, const std::string& channel, const std::vector<uint8_t>& bytes) {
    node_.server().SetClock(static_cast<int64_t>(1e6 * clock_s));
    Send(channel, bytes);
  }

  std::vector<LogEvent> journal_;
  bool fail_appends_ = false;
};

// Poses within `tolerance` (0: bit for bit, e.g. the same inputs through the same handlers
// in the same order).
void ExpectSameMap(const MergedMap& a, const MergedMap& b, double tolerance = 0.0) {
  ASSERT_EQ(a.trajectories.size(), b.trajectories.size());
  for (size_t t = 0; t < a.trajectories.size(); ++t) {
    const MergedTrajectory& x = a.trajectories[t];
    const MergedTrajectory& y = b.trajectories[t];
    EXPECT_EQ(x.robot, y.robot);
    EXPECT_EQ(x.trajectory_id, y.trajectory_id);
    EXPECT_EQ(x.anchored, y.anchored);
    EXPECT_EQ(x.pose_utimes, y.pose_utimes);
    ASSERT_EQ(x.poses.size(), y.poses.size());
    for (size_t i = 0; i < x.poses.size(); ++i) {
      EXPECT_NEAR(x.poses[i].x(), y.poses[i].x(), tolerance) << x.robot << " pose " << i;
      EXPECT_NEAR(x.poses[i].y(), y.poses[i].y(), tolerance) << x.robot << " pose " << i;
      EXPECT_NEAR(x.poses[i].theta(), y.poses[i].theta(), tolerance) << x.robot << " pose " << i;
    }
  }
  EXPECT_EQ(a.encounters.size(), b.encounters.size());
}

TEST_F(ServerNodeJournalTest, ReplayingTheJournalRebuildsTheSameGraphsAndEstimate) {
  // R1 in order with one duplicate; R2 out of order (seq 2 held until 1 comes); R3 with a
  // gap that never fills, bridged by a tick after the hold time.
  for (int32_t seq = 0; seq < 4; ++seq) {
    Receive(1.0 + seq, channels::kKeyframes, EncodeKeyframe(MakeKeyframe("R1", 11, seq)));
  }
  Receive(5.0, channels::kKeyframes, EncodeKeyframe(MakeKeyframe("R1", 11, 2)));  // duplicate
  for (int32_t seq : {0, 2, 1, 3}) {
    Receive(6.0, channels::kKeyframes, EncodeKeyframe(MakeKeyframe("R2", 12, seq)));
  }
  for (int32_t seq : {0, 1, 3, 4}) {
    Receive(7.0, channels::kKeyframes, EncodeKeyframe(MakeKeyframe("R3", 13, seq)));
  }
  // Gap not old enough: not bridged; the canonical order stage releases what has settled
  // (a tick that changed the graph is journaled).
  node_.Tick(8'000'000);
  EXPECT_EQ(node_.server().receipt().num_bridged_gaps(), 0);
  const size_t before_bridge = journal_.size();
  node_.Tick(18'000'000);  // 11 s after the gap opened: bridged (max_hold_s 10)
  ASSERT_EQ(journal_.size(), before_bridge + 1);
  EXPECT_EQ(journal_.back().channel, ServerNode::kJournalTick);
  EXPECT_EQ(node_.server().receipt().num_bridged_gaps(), 1);
  Encounter e = R1SeesR2();
  Receive(19.0, channels::kEncounters, EncodeEncounter(e));
  e.observed = "R3";
  e.utime = 3'000'000;
  e.T_observer_observed = Pose2(1.0, -2.0, 0.5);
  Receive(19.5, channels::kEncounters, EncodeEncounter(e));
  Receive(20.0, channels::kKeyframes, EncodeKeyframe(MakeKeyframe("R1", 11, 4)));
  node_.Tick(30'000'000);  // everything settled: released into the graph
  // 12 keyframes + 1 duplicate + 2 encounters + 1 keyframe, and the ticks that released.
  const auto ticks = std::count_if(journal_.begin(), journal_.end(), [](const LogEvent& e) {
    return e.channel == ServerNode::kJournalTick;
  });
  EXPECT_EQ(journal_.size() - static_cast<size_t>(ticks), 16u);
  EXPECT_EQ(node_.server().table().num_keyframes(), 13);
  EXPECT_EQ(node_.server().table().num_bridged_gaps(), 1);

  ServerNode restarted(ServerOptions{}, [](const std::string&, const std::vector<uint8_t>&) {});
  for (const LogEvent& event : journal_) EXPECT_TRUE(restarted.Replay(event));
  ExpectSameMap(node_.server().BuildMergedMap(), restarted.server().BuildMergedMap());
  EXPECT_EQ(restarted.server().update_count(), node_.server().update_count());
  EXPECT_EQ(restarted.server().table().num_keyframes(), node_.server().table().num_keyframes());
  EXPECT_EQ(restarted.server().table().num_bridged_gaps(), 1);
  EXPECT_EQ(restarted.server().rejects().count(ErrorCode::kDuplicateSequence), 1);
  EXPECT_EQ(restarted.server().rejects().total(), node_.server().rejects().total());
  const std::vector<DeliveryAck> acks = node_.server().BuildAcks();
  const std::vector<DeliveryAck> replayed_acks = restarted.server().BuildAcks();
  ASSERT_EQ(acks.size(), replayed_acks.size());
  for (size_t i = 0; i < acks.size(); ++i) {
    EXPECT_EQ(acks[i].robot, replayed_acks[i].robot);
    EXPECT_EQ(acks[i].keyframes_next, replayed_acks[i].keyframes_next);
    EXPECT_EQ(acks[i].encounters_next, replayed_acks[i].encounters_next);
  }
  // A restart's replay with the solver's updates deferred to batch steps: the same graphs
  // and tables, every event the node's, the update counter where the live one is.
  ServerNode deferred(ServerOptions{}, [](const std::string&, const std::vector<uint8_t>&) {});
  const ServerNode::JournalReplay replay = deferred.ReplayJournal(journal_, true);
  EXPECT_TRUE(replay.deferred);
  EXPECT_EQ(replay.events, static_cast<int64_t>(journal_.size()));
  EXPECT_TRUE(replay.batch_step.status.ok());
  EXPECT_TRUE(replay.batch_step.batch_step);
  EXPECT_EQ(deferred.server().update_count(), node_.server().update_count());
  EXPECT_EQ(deferred.server().stats().deferred_updates, node_.server().update_count());
  EXPECT_EQ(deferred.server().table().num_bridged_gaps(), 1);
  EXPECT_EQ(deferred.server().rejects().total(), node_.server().rejects().total());
  // Straight, consistent keyframes and encounters: the incremental estimate is already the
  // minimum, so the converged one equals it to rounding.
  const MergedMap live_map = node_.server().BuildMergedMap();
  ExpectSameMap(live_map, deferred.server().BuildMergedMap(), 1e-9);
  // With updates not deferred (the option off), ReplayJournal is the event-by-event replay.
  ServerNode full(ServerOptions{}, [](const std::string&, const std::vector<uint8_t>&) {});
  EXPECT_FALSE(full.ReplayJournal(journal_, false).deferred);
  ExpectSameMap(live_map, full.server().BuildMergedMap());

  // Replay journals nothing, and other channels are not the journal's.
  LogEvent other;
  other.channel = "SOMEONE_ELSES_CHANNEL";
  EXPECT_FALSE(restarted.Replay(other));
}

// A keyframe in the layout before keyframe_t carried encounters_relayed (journals written
// then): the same fields in anchormap.keyframe_v1_t.
std::vector<uint8_t> AsKeyframeV1(const std::vector<uint8_t>& bytes) {
  const Result<Keyframe> k = DecodeKeyframe(bytes.data(), bytes.size());
  EXPECT_TRUE(k.ok());
  anchormap::keyframe_v1_t m;
  m.utime = k->utime;
  m.robot = k->robot;
  m.trajectory_id = k->trajectory_id;
  m.seq = k->seq;
  const Pose2 poses[] = {k->T_local_pose, k->T_previous_this, k->scan.T_body_sensor};
  double* arrays[] = {m.pose, m.T_previous_this, m.sensor_offset};
  for (int i = 0; i < 3; ++i) {
    arrays[i][0] = poses[i].x();
    arrays[i][1] = poses[i].y();
    arrays[i][2] = poses[i].theta();
  }
  for (int i = 0; i < 9; ++i)
    m.T_previous_this_covariance[i] = k->T_previous_this_covariance(i / 3, i % 3);
  m.rad0 = k->scan.rad0;
  m.radstep = k->scan.radstep;
  m.max_range = k->scan.max_range;
  m.nranges = static_cast<int32_t>(k->scan.ranges.size());
  m.ranges = k->scan.ranges;
  std::vector<uint8_t> out(static_cast<size_t>(m.getEncodedSize()));
  EXPECT_EQ(m.encode(out.data(), 0, static_cast<int>(out.size())), static_cast<int>(out.size()));
  return out;
}

// A journal written before keyframes carried their count of relayed encounters is still
// read: its keyframes (the older layout, count 0: nothing revealed) replay into the same
// graphs, acknowledgements and map as the same session in today's layout.
TEST_F(ServerNodeJournalTest, AJournalOfTheOlderKeyframeLayoutIsReplayed) {
  for (int32_t seq = 0; seq < 4; ++seq) {
    Receive(1.0 + seq, channels::kKeyframes, EncodeKeyframe(MakeKeyframe("R1", 11, seq)));
    Receive(1.1 + seq, channels::kKeyframes, EncodeKeyframe(MakeKeyframe("R2", 12, seq)));
  }
  Encounter e = R1SeesR2();
  e.seq = 0;
  Receive(5.0, channels::kEncounters, EncodeEncounter(e));
  node_.Tick(30'000'000);
  ASSERT_EQ(node_.server().table().num_keyframes(), 8);
  std::vector<LogEvent> old_journal = journal_;
  int converted = 0;
  for (LogEvent& event : old_journal) {
    if (event.channel != channels::kKeyframes) continue;
    event.data = AsKeyframeV1(event.data);
    ++converted;
  }
  ASSERT_EQ(converted, 8);
  ServerNode restarted(ServerOptions{}, [](const std::string&, const std::vector<uint8_t>&) {});
  for (const LogEvent& event : old_journal) EXPECT_TRUE(restarted.Replay(event));
  EXPECT_EQ(restarted.server().rejects().total(), 0);
  EXPECT_EQ(restarted.server().table().num_keyframes(), 8);
  EXPECT_EQ(restarted.server().stats().encounters_added, 1);
  ExpectSameMap(node_.server().BuildMergedMap(), restarted.server().BuildMergedMap());
  const std::vector<DeliveryAck> acks = restarted.server().BuildAcks();
  ASSERT_EQ(acks.size(), 2u);
  EXPECT_EQ(acks[0].keyframes_next, 4);
  EXPECT_EQ(acks[0].encounters_next, 1);
}

// A restart from a snapshot taken mid-session plus the journal's tail rebuilds what the
// whole journal's replay does; a snapshot that does not match the journal is refused and
// changes nothing.
TEST_F(ServerNodeJournalTest, ASnapshotAndTheJournalsTailRebuildTheWholeReplay) {
  for (int32_t seq : {0, 1, 2}) {
    Receive(1.0 + seq, channels::kKeyframes, EncodeKeyframe(MakeKeyframe("R1", 11, seq)));
  }
  for (int32_t seq : {0, 2, 3}) {  // seq 1 missing: 2 and 3 held at the snapshot
    Receive(2.0, channels::kKeyframes, EncodeKeyframe(MakeKeyframe("R2", 12, seq)));
  }
  node_.Tick(4'000'000);
  ASSERT_GT(node_.server().receipt().num_held(), 0u);
  const JournalPosition position{static_cast<int64_t>(journal_.size()), journal_.back().utime,
                                 journal_.back().channel};
  const Result<std::vector<uint8_t>> snapshot = node_.EncodeSnapshot(position);
  ASSERT_TRUE(snapshot.ok()) << snapshot.status().message();
  Receive(5.0, channels::kKeyframes, EncodeKeyframe(MakeKeyframe("R2", 12, 1)));  // the resend
  Receive(5.5, channels::kKeyframes, EncodeKeyframe(MakeKeyframe("R2", 12, 2)));  // duplicate
  Encounter e = R1SeesR2();
  Receive(6.0, channels::kEncounters, EncodeEncounter(e));
  node_.Tick(20'000'000);

  ServerNode whole(ServerOptions{}, [](const std::string&, const std::vector<uint8_t>&) {});
  (void)whole.ReplayJournal(journal_, true);
  ServerNode restarted(ServerOptions{}, [](const std::string&, const std::vector<uint8_t>&) {});
  const Result<int64_t> covered = restarted.RestoreSnapshot(*snapshot, journal_);
  ASSERT_TRUE(covered.ok()) << covered.status().message();
  EXPECT_EQ(*covered, position.events);
  const ServerNode::JournalReplay tail =
      restarted.ReplayJournal(journal_, true, static_cast<size_t>(*covered));
  EXPECT_EQ(tail.events, static_cast<int64_t>(journal_.size()) - position.events);
  for (ServerNode* node : {&whole, &restarted}) {
    EXPECT_EQ(node->server().update_count(), node_.server().update_count());
    EXPECT_EQ(node->server().table().num_keyframes(), 7);
    EXPECT_EQ(node->server().stats().encounters_added, 1);
    EXPECT_EQ(node->server().rejects().count(ErrorCode::kDuplicateSequence), 1);
    EXPECT_EQ(node->server().receipt().num_held(), 0u);
  }
  ExpectSameMap(whole.server().BuildMergedMap(), restarted.server().BuildMergedMap(), 1e-9);
  ExpectSameMap(node_.server().BuildMergedMap(), restarted.server().BuildMergedMap(), 1e-9);

  // Not this journal's prefix: a shorter journal, another last event.
  ServerNode refused(ServerOptions{}, [](const std::string&, const std::vector<uint8_t>&) {});
  const std::vector<LogEvent> shorter(journal_.begin(), journal_.begin() + position.events - 1);
  EXPECT_FALSE(refused.RestoreSnapshot(*snapshot, shorter).ok());
  std::vector<LogEvent> other = journal_;
  other[position.events - 1].utime += 1;
  EXPECT_FALSE(refused.RestoreSnapshot(*snapshot, other).ok());
  std::vector<uint8_t> corrupt = *snapshot;
  corrupt[corrupt.size() / 3] ^= 0x40;
  EXPECT_FALSE(refused.RestoreSnapshot(corrupt, journal_).ok());
  EXPECT_EQ(refused.server().table().num_keyframes(), 0);  // unchanged
  EXPECT_EQ(refused.server().receipt().num_keyframes(), 0);
}

TEST_F(ServerNodeJournalTest, AnInputThatCannotBeJournaledIsRefusedNotApplied) {
  Receive(1.0, channels::kKeyframes, EncodeKeyframe(MakeKeyframe("R1", 11, 0)));
  fail_appends_ = true;
  Receive(2.0, channels::kKeyframes, EncodeKeyframe(MakeKeyframe("R1", 11, 1)));
  EXPECT_EQ(node_.server().receipt().num_keyframes(), 1);
  EXPECT_EQ(node_.server().rejects().count(ErrorCode::kIoError), 1);
  // The agent's resend, once the disk has room again, is accepted.
  fail_appends_ = false;
  Receive(3.0, channels::kKeyframes, EncodeKeyframe(MakeKeyframe("R1", 11, 1)));
  EXPECT_EQ(node_.server().receipt().num_keyframes(), 2);
  EXPECT_EQ(journal_.size(), 2u);
}

TEST_F(ServerNodeTest, StatusCarriesTheInstanceIdAndTheMapIsRepublishedWhenQuiet) {
  node_.set_instance_id(987654321);
  node_.PublishStatus();
  const auto& status_bytes = published_[channels::kServerStatus].at(0);
  const Result<ServerStatus> status = DecodeServerStatus(status_bytes.data(), status_bytes.size());
  ASSERT_TRUE(status.ok());
  EXPECT_EQ(status->instance_id, 987654321);

  node_.RepublishMapDue(1'000'000, 5.0);  // nothing mapped yet: nothing to repeat
  EXPECT_TRUE(published_[channels::kMapHeader].empty());
  Send(channels::kKeyframes, EncodeKeyframe(MakeKeyframe("R1", 11, 0)));
  node_.PublishDue(2'000'000);
  ASSERT_EQ(published_[channels::kMapHeader].size(), 1u);
  EXPECT_EQ(published_[channels::kMapChunks].size(), 1u);
  node_.RepublishMapDue(6'000'000, 5.0);  // 4 s after the last one: not yet
  EXPECT_EQ(published_[channels::kMapHeader].size(), 1u);
  node_.RepublishMapDue(7'000'000, 5.0);  // the header and every chunk again
  EXPECT_EQ(published_[channels::kMapHeader].size(), 2u);
  EXPECT_EQ(published_[channels::kMapChunks].size(), 2u);
  EXPECT_EQ(published_[channels::kAnchorCovariances].size(), 2u);
  EXPECT_EQ(published_[channels::kMapChunks][0], published_[channels::kMapChunks][1]);
  node_.RepublishMapDue(8'000'000, 5.0);
  EXPECT_EQ(published_[channels::kMapHeader].size(), 2u);
}

// A live tick puts into the graph only what its release budget lets through; a replayed tick
// puts in as many (the journaled count), not all that was due then. Otherwise an input that
// came between two ticks (here an encounter) is in order live but late in the replay, and
// with the scan sources on a late input changes decisions.
TEST(ServerNodeReplayTest, AReplayedTickReleasesAsManyInputsAsTheLiveTickDid) {
  int64_t now = 0;
  // Every reading of the node's clock 50 ms later: the 80 ms budget lets one input through.
  const ServerNode::Clock stepping = [&now] { return now += 50'000; };
  const auto nothing = [](const std::string&, const std::vector<uint8_t>&) {};
  std::vector<LogEvent> journal;
  ServerOptions options;
  options.server.order.release_per_call = 0;  // as online: only the ticks release
  ServerNode live(options, nothing, stepping);
  live.SetJournal(AppendToMemory(&journal));
  const auto receive = [&live](int64_t clock, const std::string& channel,
                               const std::vector<uint8_t>& bytes) {
    live.server().SetClock(clock);
    live.OnMessage(channel, bytes.data(), bytes.size());
  };
  for (int32_t seq = 0; seq < 6; ++seq) {
    receive(1'000'000, channels::kKeyframes, EncodeKeyframe(MakeKeyframe("R1", 11, seq)));
    receive(1'000'000, channels::kKeyframes, EncodeKeyframe(MakeKeyframe("R2", 12, seq)));
  }
  // Three ticks: R1's and R2's first keyframes (1 s) and R1's second (2 s) go in.
  for (int i = 0; i < 3; ++i) live.Tick(20'000'000 + i * 100'000);
  EXPECT_EQ(live.server().order_stats().released, 3);
  receive(21'000'000, channels::kEncounters, EncodeEncounter(R1SeesR2()));  // at 2 s
  for (int i = 0; i < 20; ++i) live.Tick(40'000'000 + i * 100'000);
  EXPECT_EQ(live.server().order_stats().released, 13);
  EXPECT_EQ(live.server().order_stats().late, 0);
  ASSERT_EQ(live.server().encounter_links().size(), 1u);

  ServerNode replayed(options, nothing, stepping);
  for (const LogEvent& event : journal) EXPECT_TRUE(replayed.Replay(event));
  EXPECT_EQ(replayed.server().order_stats().late, 0);
  EXPECT_EQ(replayed.server().encounter_links(), live.server().encounter_links());
  ExpectSameMap(live.server().BuildMergedMap(), replayed.server().BuildMergedMap());

  // The same journal without the counts (as written before them): the first replayed tick
  // releases all that was due, and the encounter comes late.
  ServerNode uncounted(options, nothing, stepping);
  for (LogEvent event : journal) {
    if (event.channel == ServerNode::kJournalTick) event.data.clear();
    EXPECT_TRUE(uncounted.Replay(event));
  }
  EXPECT_EQ(uncounted.server().order_stats().late, 1);
}

// A restarted server's ResumeClocks is journaled, and a later restart's replay resumes the
// clocks at the same point: a gap open across the first restart is not bridged by the
// replay when the live server (whose hold counted from its restart) did not bridge it.
TEST(ServerNodeReplayTest, AReplayResumesTheClocksWhereTheRestartedServerDid) {
  const auto nothing = [](const std::string&, const std::vector<uint8_t>&) {};
  ServerOptions options;
  options.server.order.release_per_call = 0;  // as online: only the ticks release
  std::vector<LogEvent> journal;
  const ServerNode::JournalAppend append = AppendToMemory(&journal);
  const auto receive = [](ServerNode* node, double clock_s, const Keyframe& keyframe) {
    node->server().SetClock(static_cast<int64_t>(1e6 * clock_s));
    const std::vector<uint8_t> bytes = EncodeKeyframe(keyframe);
    node->OnMessage(channels::kKeyframes, bytes.data(), bytes.size());
  };
  {
    // The first server: R1's seq 2 never comes before it dies (a gap opened at 4 s, when
    // seq 3 came).
    ServerNode first(options, nothing);
    first.SetJournal(append);
    for (int32_t seq : {0, 1, 3}) receive(&first, 1.0 + seq, MakeKeyframe("R1", 11, seq));
    first.Tick(3'500'000);
  }
  // Restarted at 12 s (8 s after the gap opened, max_hold_s 10): its clocks resume there.
  ServerNode second(options, nothing);
  second.SetJournal(append);
  second.ReplayJournal(journal, true);
  second.ResumeClocks(12'000'000);
  EXPECT_EQ(journal.back().channel, ServerNode::kJournalResume);
  // 10.5 s after the gap opened, 2.5 s after the restart; it releases R1's seq 1 (settled),
  // so it is journaled.
  second.Tick(14'500'000);
  EXPECT_EQ(second.server().receipt().num_bridged_gaps(), 0);
  receive(&second, 15.0, MakeKeyframe("R1", 11, 2));  // the resend fills it
  second.Tick(30'000'000);
  EXPECT_EQ(second.server().receipt().num_bridged_gaps(), 0);
  EXPECT_EQ(second.server().table().num_keyframes(), 4);

  // A later restart replays it all alike: no gap bridged, seq 2 accepted.
  ServerNode third(options, nothing);
  third.ReplayJournal(journal, true);
  EXPECT_EQ(third.server().receipt().num_bridged_gaps(), 0);
  EXPECT_EQ(third.server().table().num_keyframes(), 4);
  EXPECT_EQ(third.server().rejects().total(), second.server().rejects().total());

  // Without the resume event (a journal of before), the replay bridges the gap at the
  // tick of 14.5 s and then refuses the resent keyframe: what the restarts differed on.
  std::vector<LogEvent> without;
  for (const LogEvent& event : journal) {
    if (event.channel != ServerNode::kJournalResume) without.push_back(event);
  }
  ServerNode old(options, nothing);
  old.ReplayJournal(without, true);
  EXPECT_EQ(old.server().receipt().num_bridged_gaps(), 1);
  EXPECT_EQ(old.server().rejects().count(ErrorCode::kLateSequence), 1);
}

}  // namespace
}  // namespace anchormap
