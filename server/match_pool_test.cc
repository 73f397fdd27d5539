#include "server/match_pool.h"

#include <algorithm>
#include <atomic>
#include <mutex>
#include <vector>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

MatchResult ResultAt(double x) {
  MatchResult result;
  result.pose = Pose2(x, 2.0 * x, 0.1);
  result.score = 0.75;
  result.overlap = 0.9;
  return result;
}

MatchTag Tag(int32_t query, int32_t reference) {
  return {PoseKey{TrajectoryId(0), query}, PoseKey{TrajectoryId(1), reference}};
}

// Every computed result is recorded with its submission ordinal and tag before it is
// used, whatever the worker count.
TEST(MatchPoolTest, EveryResultIsRecordedWithItsOrdinalBeforeItIsUsed) {
  for (const int workers : {0, 2}) {
    MatchPool pool(workers);
    std::mutex mutex;
    std::vector<RecordedMatch> recorded;
    pool.SetRecorder([&](const RecordedMatch& match) {
      std::lock_guard<std::mutex> lock(mutex);
      recorded.push_back(match);
    });
    std::vector<std::shared_future<std::optional<MatchResult>>> futures;
    for (int i = 0; i < 6; ++i) {
      futures.push_back(pool.Submit(Tag(i, 10 + i), [i]() -> std::optional<MatchResult> {
        if (i == 3) return std::nullopt;  // no match is a result too
        return ResultAt(i);
      }));
    }
    for (int i = 0; i < 6; ++i) {
      const std::optional<MatchResult> result = futures[static_cast<size_t>(i)].get();
      std::lock_guard<std::mutex> lock(mutex);
      const auto it = std::find_if(recorded.begin(), recorded.end(),
                                   [i](const RecordedMatch& m) { return m.ordinal == i; });
      ASSERT_NE(it, recorded.end()) << "result " << i << " used before it was recorded";
      EXPECT_TRUE(it->tag == Tag(i, 10 + i));
      EXPECT_EQ(it->result.has_value(), i != 3);
      if (result) {
        EXPECT_EQ(it->result->pose.x(), result->pose.x());
      }
    }
    EXPECT_EQ(pool.stats().submitted, 6);
    EXPECT_EQ(pool.stats().reused, 0);
  }
}

// A restart's preloaded results are served instead of running the jobs (and not recorded
// again); a result whose tag is not the job's, or a job with none, runs.
TEST(MatchPoolTest, PreloadedResultsAreServedOnlyForTheSameOrdinalAndTag) {
  MatchPool pool(2);
  std::atomic<int> ran{0};
  std::atomic<int> recorded{0};
  pool.SetRecorder([&](const RecordedMatch&) { ++recorded; });
  pool.Preload({{0, Tag(0, 10), 0, ResultAt(100.0)},
                {1, Tag(1, 11), 0, std::nullopt},
                {2, Tag(7, 7), 0, ResultAt(300.0)}});
  EXPECT_EQ(pool.preloaded(), 3u);
  auto job = [&ran](double x) {
    return [&ran, x]() -> std::optional<MatchResult> {
      ++ran;
      return ResultAt(x);
    };
  };
  const auto r0 = pool.Submit(Tag(0, 10), job(1.0)).get();
  const auto r1 = pool.Submit(Tag(1, 11), job(2.0)).get();
  const auto r2 = pool.Submit(Tag(2, 12), job(3.0)).get();  // the tag differs: run
  const auto r3 = pool.Submit(Tag(3, 13), job(4.0)).get();  // none preloaded: run
  ASSERT_TRUE(r0.has_value());
  EXPECT_EQ(r0->pose.x(), 100.0);
  EXPECT_FALSE(r1.has_value());
  ASSERT_TRUE(r2.has_value());
  EXPECT_EQ(r2->pose.x(), 3.0);
  ASSERT_TRUE(r3.has_value());
  EXPECT_EQ(r3->pose.x(), 4.0);
  EXPECT_EQ(ran.load(), 2);
  EXPECT_EQ(recorded.load(), 2);
  EXPECT_EQ(pool.stats().submitted, 4);
  EXPECT_EQ(pool.stats().reused, 2);
  EXPECT_EQ(pool.stats().mismatched, 1);
  EXPECT_EQ(pool.preloaded(), 0u);
}

// Results journaled under other options (another fingerprint, or none: an older journal)
// are run again and counted, and the new results are recorded under the pool's own.
TEST(MatchPoolTest, ResultsOfOtherOptionsAreRunAgainAndCounted) {
  MatchPool pool(0);
  pool.SetOptionsFingerprint(77);
  std::vector<RecordedMatch> recorded;
  pool.SetRecorder([&](const RecordedMatch& match) { recorded.push_back(match); });
  pool.Preload({{0, Tag(0, 10), 77, ResultAt(100.0)},
                {1, Tag(1, 11), 78, ResultAt(200.0)},
                {2, Tag(2, 12), 0, ResultAt(300.0)}});
  auto job = [](double x) { return [x]() -> std::optional<MatchResult> { return ResultAt(x); }; };
  EXPECT_EQ(pool.Submit(Tag(0, 10), job(1.0)).get()->pose.x(), 100.0);
  EXPECT_EQ(pool.Submit(Tag(1, 11), job(2.0)).get()->pose.x(), 2.0);
  EXPECT_EQ(pool.Submit(Tag(2, 12), job(3.0)).get()->pose.x(), 3.0);
  EXPECT_EQ(pool.stats().reused, 1);
  EXPECT_EQ(pool.stats().other_options, 2);
  EXPECT_EQ(pool.stats().mismatched, 0);
  ASSERT_EQ(recorded.size(), 2u);
  for (const RecordedMatch& m : recorded) EXPECT_EQ(m.options_fingerprint, 77u);
}

// The kind is part of the tag: a wide search's result is not served to the local match of
// the same two keyframes (its ambiguity rival).
TEST(MatchPoolTest, TheKindOfSearchIsPartOfTheTag) {
  MatchPool pool(0);
  const MatchTag wide{PoseKey{TrajectoryId(0), 40}, PoseKey{TrajectoryId(0), 5},
                      MatchKind::kLoopWide};
  MatchTag rival = wide;
  rival.kind = MatchKind::kLoopRival;
  pool.Preload({{0, wide, 0, ResultAt(100.0)}});
  EXPECT_EQ(
      pool.Submit(rival, [] { return std::optional<MatchResult>(ResultAt(1.0)); }).get()->pose.x(),
      1.0);
  EXPECT_EQ(pool.stats().mismatched, 1);
  EXPECT_EQ(pool.stats().reused, 0);
}

}  // namespace
}  // namespace anchormap
