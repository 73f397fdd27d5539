#include "server/delivery.h"

#include <gtest/gtest.h>

namespace anchormap {
namespace {

using Ranges = std::vector<std::pair<int32_t, int32_t>>;

TEST(SeqWindowTest, RecognisesDuplicatesAndNamesTheGaps) {
  SeqWindow window;
  EXPECT_TRUE(window.Insert(0));
  EXPECT_TRUE(window.Insert(3));
  EXPECT_TRUE(window.Insert(4));
  EXPECT_TRUE(window.Insert(7));
  EXPECT_FALSE(window.Insert(0));
  EXPECT_FALSE(window.Insert(4));
  EXPECT_EQ(window.next(), 1);
  EXPECT_EQ(window.Missing(), (Ranges{{1, 2}, {5, 6}}));
  EXPECT_TRUE(window.Insert(2));
  EXPECT_TRUE(window.Insert(1));
  EXPECT_EQ(window.next(), 5);
  EXPECT_EQ(window.Missing(), (Ranges{{5, 6}}));
  EXPECT_TRUE(window.Insert(5));
  EXPECT_TRUE(window.Insert(6));
  EXPECT_EQ(window.next(), 8);
  EXPECT_TRUE(window.Missing().empty());
  EXPECT_FALSE(window.Insert(6));
  // Numbers that will never come (a restarted server misses the early ones) are given up.
  EXPECT_TRUE(window.Insert(11));
  EXPECT_TRUE(window.Insert(13));
  EXPECT_EQ(window.GiveUpMissing(), 4);  // 8, 9, 10, 12
  EXPECT_EQ(window.next(), 14);
  EXPECT_TRUE(window.Missing().empty());
  EXPECT_FALSE(window.Insert(9));
}

// A keyframe's count of relayed encounters reveals the ones after the highest arrived:
// the last encounter lost before a quiet period is missing although nothing came after it.
TEST(SeqWindowTest, AnExpectedCountRevealsTheMissingTail) {
  SeqWindow window;
  EXPECT_TRUE(window.Insert(0));
  EXPECT_TRUE(window.Insert(1));
  EXPECT_TRUE(window.Missing().empty());
  window.Expect(3);  // seq 2 was relayed before the keyframe that says 3
  EXPECT_EQ(window.Missing(), (Ranges{{2, 2}}));
  window.Expect(2);  // an older keyframe's count changes nothing
  EXPECT_EQ(window.Missing(), (Ranges{{2, 2}}));
  EXPECT_TRUE(window.Insert(4));  // both: a gap below an arrival and the expected tail
  window.Expect(6);
  EXPECT_EQ(window.Missing(), (Ranges{{2, 3}, {5, 5}}));
  EXPECT_TRUE(window.Insert(2));
  EXPECT_TRUE(window.Insert(3));
  EXPECT_EQ(window.next(), 5);
  EXPECT_EQ(window.Missing(), (Ranges{{5, 5}}));
  EXPECT_TRUE(window.Insert(5));
  EXPECT_EQ(window.next(), 6);
  EXPECT_TRUE(window.Missing().empty());
  // Given up, the expected ones count too; later arrivals of them are duplicates.
  window.Expect(9);
  EXPECT_EQ(window.GiveUpMissing(), 3);  // 6, 7, 8
  EXPECT_EQ(window.next(), 9);
  EXPECT_TRUE(window.Missing().empty());
  EXPECT_FALSE(window.Insert(7));
  EXPECT_EQ(window.GiveUpMissing(), 0);
}

TEST(ResendTrackerTest, AsksATrajectoryAtMostOncePerPeriod) {
  DeliveryOptions options;
  options.resend_period_s = 0.5;
  ResendTracker tracker(options);
  EXPECT_TRUE(tracker.Due({"R1", 7}, 1'000'000));
  EXPECT_FALSE(tracker.Due({"R1", 7}, 1'400'000));
  EXPECT_TRUE(tracker.Due({"R1", 8}, 1'400'000));  // another trajectory
  EXPECT_TRUE(tracker.Due({"R1", 7}, 1'500'000));
}

}  // namespace
}  // namespace anchormap
