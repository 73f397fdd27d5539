#include "common/solver/keys.h"

#include <type_traits>
#include <unordered_set>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

// The point of the type: a bare number (the agent's id on the bus, a loop counter) does
// not silently become a solver trajectory.
static_assert(!std::is_convertible_v<int64_t, TrajectoryId>);
static_assert(!std::is_convertible_v<int, TrajectoryId>);
static_assert(!std::is_convertible_v<TrajectoryId, int64_t>);
static_assert(std::is_constructible_v<TrajectoryId, int64_t>);

TEST(KeysTest, KeysNameTheirTrajectoryAndIndex) {
  const TrajectoryId t(7);
  EXPECT_EQ(Key(PoseKey{t, 3}).ToString(), "pose(7,3)");
  EXPECT_EQ(Key(AnchorKey{t}).ToString(), "anchor(7)");
  EXPECT_TRUE(Key(AnchorKey{t}).is_anchor());
  EXPECT_FALSE(Key(PoseKey{t, 0}).is_anchor());
  EXPECT_EQ(Key(PoseKey{t, 3}).pose(), (PoseKey{t, 3}));
  EXPECT_LT(TrajectoryId(2), TrajectoryId(10));
}

TEST(KeysTest, HashSeparatesPosesAnchorsAndTrajectories) {
  std::unordered_set<Key, KeyHash> keys;
  for (int64_t t = 0; t < 20; ++t) {
    keys.insert(AnchorKey{TrajectoryId(t)});
    for (int32_t i = 0; i < 50; ++i) keys.insert(PoseKey{TrajectoryId(t), i});
  }
  EXPECT_EQ(keys.size(), 20u * 51u);
  std::unordered_set<TrajectoryId> ids{TrajectoryId(1), TrajectoryId(2), TrajectoryId(1)};
  EXPECT_EQ(ids.size(), 2u);
}

}  // namespace
}  // namespace anchormap
