#include "server/submap_cache.h"

#include <memory>

#include <gtest/gtest.h>

#include "server/mapping_server.h"
#include "tests/testing/straight_keyframes.h"

namespace anchormap {
namespace {

// One straight trajectory of 30 keyframes with scans, solved.
class SubmapCacheTest : public ::testing::Test {
 protected:
  void SetUp() override {
    MappingServerOptions options;
    options.loop_closures = false;
    options.scan_encounters = false;
    server_ = std::make_unique<MappingServer>(options);
    for (int32_t seq = 0; seq < 30; ++seq) {
      ASSERT_TRUE(server_->OnKeyframe(testing::StraightKeyframe("R1", 1, seq, 60)).ok());
    }
    server_->Flush();
    record_ = server_->table().FindBySolverId(t_);
    ASSERT_NE(record_, nullptr);
  }
  SubmapDrawing Draw(int32_t center, int half_width) const {
    return DrawKeyframeSubmap(*record_, server_->smoother(), {t_, center}, half_width, 15.0);
  }

  const TrajectoryId t_{0};
  std::unique_ptr<MappingServer> server_;
  const TrajectoryRecord* record_ = nullptr;
  const ScanReferenceOptions reference_{};
};

TEST_F(SubmapCacheTest, ASecondUseOfTheSameDrawingIsServedFromTheCache) {
  SubmapCache cache({}, 15.0, reference_);
  const auto first = cache.Get(*record_, Draw(10, 2), 2);
  const auto second = cache.Get(*record_, Draw(10, 2), 2);
  ASSERT_TRUE(first);
  EXPECT_EQ(first, second);
  // Another half width around the same centre is another submap.
  const auto wider = cache.Get(*record_, Draw(10, 4), 4);
  EXPECT_NE(wider, first);
  EXPECT_EQ(cache.stats().hits, 1);
  EXPECT_EQ(cache.stats().builds, 2);
  EXPECT_EQ(cache.stats().held, 2);
  EXPECT_EQ(cache.stats().bytes,
            static_cast<int64_t>(ReferenceBytes(*first) + ReferenceBytes(*wider)));
}

TEST_F(SubmapCacheTest, AnUnkeptBuildEvictsNothing) {
  SubmapCache cache(SubmapCacheOptions{0.0, 0.0, 0.0}, 15.0, reference_);
  const auto kept = cache.Get(*record_, Draw(10, 2), 2);
  const auto unkept = cache.BuildUnkept(*record_, Draw(20, 4));
  ASSERT_TRUE(unkept);
  EXPECT_TRUE(
      unkept->SameLikelihood(*BuildKeyframeSubmap(*record_, Draw(20, 4), 15.0, reference_)));
  EXPECT_EQ(cache.Get(*record_, Draw(10, 2), 2), kept);  // still held under a budget of 0
  EXPECT_EQ(cache.stats().builds, 2);
  EXPECT_EQ(cache.stats().hits, 1);
  EXPECT_EQ(cache.stats().held, 1);
  EXPECT_EQ(cache.stats().evictions, 0);
  EXPECT_EQ(cache.stats().bytes, static_cast<int64_t>(ReferenceBytes(*kept)));
}

TEST_F(SubmapCacheTest, TheBudgetEvictsTheLeastRecentlyUsedAndARebuildHasTheSameBits) {
  // A budget of about two references of this size.
  const auto probe = BuildKeyframeSubmap(*record_, Draw(10, 2), 15.0, reference_);
  ASSERT_TRUE(probe);
  SubmapCacheOptions options;
  options.budget_mb = 2.5 * static_cast<double>(ReferenceBytes(*probe)) / 1e6;
  SubmapCache cache(options, 15.0, reference_);
  const auto a = cache.Get(*record_, Draw(10, 2), 2);
  const auto b = cache.Get(*record_, Draw(15, 2), 2);
  EXPECT_EQ(cache.Get(*record_, Draw(10, 2), 2), a);   // a is now the most recent
  const auto c = cache.Get(*record_, Draw(20, 2), 2);  // evicts b
  EXPECT_EQ(cache.stats().evictions, 1);
  EXPECT_EQ(cache.stats().held, 2);
  EXPECT_LE(static_cast<double>(cache.stats().bytes), options.budget_mb * 1e6);
  EXPECT_EQ(cache.Get(*record_, Draw(10, 2), 2), a);  // still held
  const auto b_again = cache.Get(*record_, Draw(15, 2), 2);
  ASSERT_TRUE(b_again);
  EXPECT_NE(b_again, b);                     // built again...
  EXPECT_TRUE(b->SameLikelihood(*b_again));  // ...with the same bits
  EXPECT_EQ(cache.stats().builds, 4);
  EXPECT_EQ(cache.stats().evictions, 2);  // c, the least recently used, went
  // A budget of 0 still keeps the one reference just built.
  SubmapCache none(SubmapCacheOptions{0.0, 0.0, 0.0}, 15.0, reference_);
  EXPECT_TRUE(none.Get(*record_, Draw(10, 2), 2));
  EXPECT_EQ(none.stats().held, 1);
}

TEST_F(SubmapCacheTest, AMovedDrawingIsReusedOnlyWithinTheTolerance) {
  SubmapDrawing drawing = Draw(10, 2);
  SubmapDrawing moved = drawing;
  for (auto& [index, pose] : moved.T_center_keyframes) {
    pose = Pose2(pose.x() + 0.004, pose.y(), pose.theta() + 0.001);
  }
  SubmapCache exact({}, 15.0, reference_);
  const auto first = exact.Get(*record_, drawing, 2);
  EXPECT_NE(exact.Get(*record_, moved, 2), first);  // tolerance 0: the same bits only
  EXPECT_EQ(exact.stats().builds, 2);
  EXPECT_EQ(exact.stats().held, 1);  // the redrawn one replaced the first

  SubmapCache tolerant(SubmapCacheOptions{512.0, 0.005, 0.002}, 15.0, reference_);
  const auto kept = tolerant.Get(*record_, drawing, 2);
  EXPECT_EQ(tolerant.Get(*record_, moved, 2), kept);
  SubmapDrawing far = drawing;
  far.T_center_keyframes.back().second =
      Pose2(far.T_center_keyframes.back().second.x() + 0.01,
            far.T_center_keyframes.back().second.y(), far.T_center_keyframes.back().second.theta());
  EXPECT_NE(tolerant.Get(*record_, far, 2), kept);
  // A one-scan submap is drawn at the identity whatever the estimate: always reused.
  const auto alone = tolerant.Get(*record_, Draw(12, 0), 0);
  EXPECT_EQ(tolerant.Get(*record_, Draw(12, 0), 0), alone);
}

TEST_F(SubmapCacheTest, AnEmptyDrawingIsNotCachedAndBadOptionsAreRefused) {
  SubmapCache cache({}, 15.0, reference_);
  SubmapDrawing empty = Draw(10, 2);
  empty.num_points = 0;
  EXPECT_EQ(cache.Get(*record_, empty, 2), nullptr);
  EXPECT_EQ(cache.stats().held, 0);
  EXPECT_FALSE((SubmapCacheOptions{-1.0, 0.0, 0.0}).Validate().ok());
  EXPECT_FALSE((SubmapCacheOptions{1.0, -0.1, 0.0}).Validate().ok());
  EXPECT_TRUE(SubmapCacheOptions{}.Validate().ok());
}

}  // namespace
}  // namespace anchormap
