// The scan-matching sources' results in the journal (ServerNode::kJournalMatch): a restart
// reuses them instead of matching again and rebuilds the same graphs, estimate and source
// state as the uninterrupted server.

#include <algorithm>
#include <cmath>
#include <mutex>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/bus/channels.h"
#include "common/bus/codec.h"
#include "server/node/server_node.h"
#include "server/recorded_match_codec.h"
#include "tests/scan_testing/scan_scenarios.h"

namespace anchormap {
namespace {

// The server's clock (release budget, future check) far ahead of the data: every tick
// releases all that is due, whatever the machine's speed.
int64_t FarClock() { return int64_t{4'000'000'000'000'000}; }

ServerOptions ScanOptions() {
  ServerOptions options;
  options.server.loop_closures = true;
  options.server.scan_encounters = true;
  options.server.match_workers = 2;
  // No direct encounters to wait for: a short hold keeps the test's global searches few.
  options.server.scan.first_join_hold_s = 5.0;
  return options;
}

// One message or timer tick of the live session, as the online main sees them.
struct Step {
  int64_t clock = 0;
  std::vector<uint8_t> keyframe;  // empty: a timer tick at `clock`
};

// R1 and R2 lap the LoopWorld block from opposite corners, keyframes interleaved, each
// received 0.1 s after its time, a tick after each pair.
std::vector<Step> Session() {
  const testing::SyntheticWorld world = testing::LoopWorld();
  const testing::OdometryNoise noise{0.01, 0.005};
  const std::vector<Keyframe> k1 =
      testing::DriveKeyframes(world, testing::LoopWorldLap(0, 115), "R1", 1, 1'000'000, noise, 1);
  const std::vector<Keyframe> k2 = testing::DriveKeyframes(world, testing::LoopWorldLap(50, 115),
                                                           "R2", 2, 1'000'000, noise, 101);
  std::vector<Step> steps;
  for (size_t i = 0; i < k1.size(); ++i) {
    for (const Keyframe& k : {k1[i], k2[i]})
      steps.push_back({k.utime + 100'000, EncodeKeyframe(k)});
    steps.push_back({k1[i].utime + 200'000, {}});
  }
  steps.push_back({steps.back().clock + 10'000'000, {}});  // everything settled
  return steps;
}

void Apply(const Step& step, ServerNode* node) {
  if (step.keyframe.empty()) {
    node->Tick(step.clock);
    return;
  }
  node->server().SetClock(step.clock);
  node->OnMessage(channels::kKeyframes, step.keyframe.data(), step.keyframe.size());
}

void Publishes(const std::string&, const std::vector<uint8_t>&) {}

// Same links, keyframes and every pose within `tolerance`.
void ExpectSameServer(MappingServer& a, MappingServer& b, double tolerance) {
  EXPECT_EQ(a.encounter_links(), b.encounter_links());
  EXPECT_EQ(a.table().num_keyframes(), b.table().num_keyframes());
  EXPECT_EQ(a.update_count(), b.update_count());
  EXPECT_EQ(a.stats().added_by_kind, b.stats().added_by_kind);
  const MergedMap x = a.BuildMergedMap();
  const MergedMap y = b.BuildMergedMap();
  ASSERT_EQ(x.trajectories.size(), y.trajectories.size());
  double largest = 0.0;
  for (size_t t = 0; t < x.trajectories.size(); ++t) {
    ASSERT_EQ(x.trajectories[t].poses.size(), y.trajectories[t].poses.size());
    EXPECT_EQ(x.trajectories[t].anchored, y.trajectories[t].anchored);
    for (size_t i = 0; i < x.trajectories[t].poses.size(); ++i) {
      const Pose2& p = x.trajectories[t].poses[i];
      const Pose2& q = y.trajectories[t].poses[i];
      largest = std::max({largest, std::abs(p.x() - q.x()), std::abs(p.y() - q.y()),
                          std::abs(p.theta() - q.theta())});
    }
  }
  EXPECT_LE(largest, tolerance);
  // The sources' own figures (candidates, rejections by reason, searches) follow the
  // counters' part of the status line, after the rejections.
  const std::string la = a.StatusLine(), lb = b.StatusLine();
  EXPECT_EQ(la.substr(la.find(" rejected:")), lb.substr(lb.find(" rejected:")));
}

TEST(ScanJournalTest, ARestartReusesTheJournaledMatchesAndEndsWithTheUninterruptedMap) {
  const std::vector<Step> steps = Session();
  std::mutex mutex;
  std::vector<LogEvent> journal;
  ServerNode live(ScanOptions(), Publishes, FarClock);
  live.SetJournal(AppendToMemory(&journal, &mutex));
  std::vector<size_t> journal_at;  // the journal's length before each step
  for (const Step& step : steps) {
    {
      std::lock_guard<std::mutex> lock(mutex);
      journal_at.push_back(journal.size());
    }
    Apply(step, &live);
  }
  live.server().Flush();
  live.SetJournal(nullptr);
  const MappingServerStats& stats = live.server().stats();
  // The scenario exercises both sources (else the test proves nothing).
  EXPECT_GT(stats.added_by_kind[static_cast<int>(ConstraintKind::kLoopClosure)], 0);
  EXPECT_GT(stats.added_by_kind[static_cast<int>(ConstraintKind::kScanEncounter)], 0);
  const int64_t live_matches = live.server().match_pool().stats().submitted;
  const auto matches = std::count_if(journal.begin(), journal.end(), [](const LogEvent& e) {
    return e.channel == ServerNode::kJournalMatch;
  });
  EXPECT_EQ(matches, live_matches);  // every result journaled once

  // A restart with the whole journal: no match runs again; the same map bit for bit.
  ServerNode whole(ScanOptions(), Publishes, FarClock);
  const ServerNode::JournalReplay replay = whole.ReplayJournal(journal, /*defer_updates=*/true);
  EXPECT_FALSE(replay.deferred);  // the sources read the estimate
  EXPECT_EQ(replay.matches_journaled, live_matches);
  EXPECT_EQ(replay.matches_run, 0);
  whole.server().Flush();  // the matches of the live Flush too
  EXPECT_EQ(whole.server().match_pool().stats().submitted, live_matches);
  EXPECT_EQ(whole.server().match_pool().stats().reused, live_matches);
  ExpectSameServer(live.server(), whole.server(), 0.0);

  // Other worker counts give the same results (the fingerprint leaves them out): reused.
  ServerOptions one_worker = ScanOptions();
  one_worker.server.match_workers = 0;
  ServerNode serial(one_worker, Publishes, FarClock);
  const ServerNode::JournalReplay serial_replay = serial.ReplayJournal(journal, true);
  EXPECT_EQ(serial_replay.matches_run, 0);
  EXPECT_EQ(serial_replay.matches_other_options, 0);

  // A restart under other matcher options (a point sigma 10 % wider changes every score),
  // from the journal of the session's first third (every match it runs costs): no
  // journaled result is reused, each job at a journaled ordinal is matched again and
  // counted, and the new results are journaled under the new fingerprint.
  std::vector<LogEvent> first_third;
  {
    std::lock_guard<std::mutex> lock(mutex);
    first_third.assign(journal.begin(),
                       journal.begin() + static_cast<long>(journal_at[steps.size() / 3]));
  }
  const int64_t first_third_matches =
      std::count_if(first_third.begin(), first_third.end(),
                    [](const LogEvent& e) { return e.channel == ServerNode::kJournalMatch; });
  ASSERT_GT(first_third_matches, 0);
  ServerOptions other = ScanOptions();
  other.server.loop.match.point_sigma_m *= 1.1;
  other.server.scan.match.point_sigma_m *= 1.1;
  ServerNode changed(other, Publishes, FarClock);
  EXPECT_NE(changed.server().match_pool().options_fingerprint(),
            live.server().match_pool().options_fingerprint());
  std::mutex changed_mutex;
  std::vector<LogEvent> changed_journal;
  changed.SetJournal(AppendToMemory(&changed_journal, &changed_mutex));
  const ServerNode::JournalReplay changed_replay = changed.ReplayJournal(first_third, true);
  changed.SetJournal(nullptr);
  const MatchPoolStats& changed_stats = changed.server().match_pool().stats();
  EXPECT_EQ(changed_replay.matches_reused, 0);
  EXPECT_GT(changed_replay.matches_run, 0);
  EXPECT_EQ(changed_replay.matches_run, changed_stats.submitted);
  EXPECT_EQ(changed_replay.matches_other_options,
            std::min(changed_stats.submitted, first_third_matches));
  EXPECT_EQ(changed_replay.matches_mismatched, 0);
  for (const LogEvent& event : changed_journal) {
    if (event.channel != ServerNode::kJournalMatch) continue;
    const Result<RecordedMatch> m = DecodeRecordedMatch(event.data.data(), event.data.size());
    ASSERT_TRUE(m.ok());
    EXPECT_EQ(m->options_fingerprint, changed.server().match_pool().options_fingerprint());
  }

  // Killed at two moments (after a step, with what the journal held then), restarted
  // and fed the rest of the session: the uninterrupted server's graphs and estimate.
  for (const size_t crash : {steps.size() / 3, 2 * steps.size() / 3}) {
    SCOPED_TRACE("killed after step " + std::to_string(crash));
    std::vector<LogEvent> prefix;
    {
      std::lock_guard<std::mutex> lock(mutex);
      prefix.assign(journal.begin(), journal.begin() + static_cast<long>(journal_at[crash]));
    }
    ServerNode restarted(ScanOptions(), Publishes, FarClock);
    const ServerNode::JournalReplay r = restarted.ReplayJournal(prefix, true);
    EXPECT_GT(r.matches_reused, 0);
    // A match still running at the crash is run again; most were journaled.
    EXPECT_LE(r.matches_run, r.matches_reused / 10 + 4);
    std::mutex restarted_mutex;
    std::vector<LogEvent> tail;
    restarted.SetJournal(AppendToMemory(&tail, &restarted_mutex));
    for (size_t i = crash; i < steps.size(); ++i) Apply(steps[i], &restarted);
    restarted.server().Flush();
    restarted.SetJournal(nullptr);
    ExpectSameServer(live.server(), restarted.server(), 1e-9);
  }
}

}  // namespace
}  // namespace anchormap
