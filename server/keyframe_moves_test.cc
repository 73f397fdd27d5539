#include "server/keyframe_moves.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <random>
#include <vector>

#include "common/geometry/angle.h"

namespace anchormap {
namespace {

// A grid's placed poses and KeyframeGrid::Displacement's measure, kept by hand.
struct Placed {
  std::map<uint64_t, Pose2> pose;
  std::map<uint64_t, double> reach;
  std::optional<double> Displacement(uint64_t key, const Pose2& at) const {
    const auto it = pose.find(key);
    if (it == pose.end()) return std::nullopt;
    return (at.translation() - it->second.translation()).norm() +
           std::abs(AngleDifference(at.theta(), it->second.theta())) * reach.at(key);
  }
};

struct TestKeyframe {
  uint64_t node;
  std::optional<Pose2> offset;
  double reach;
};

// The grid's lever: the offset's length plus the reach.
double Lever(const TestKeyframe& k) {
  return (k.offset ? k.offset->translation().norm() : 0.0) + k.reach;
}

// Random sequences of node moves (most below a cell, some across many), keyframes added onto
// old and new nodes, budgets that defer some moves, complete passes and restarts from
// scratch: every pass finds exactly the keyframes a scan of all of them finds past the
// tolerance, with the same displacement and pose bits, while skipping the nodes that did
// not move far.
TEST(KeyframeMovesTest, FindsWhatAScanOfEveryKeyframeFindsOnRandomSequences) {
  constexpr double kTolerance = 0.05;
  int64_t skipped = 0, examined = 0, found = 0;
  for (uint32_t seed = 1; seed <= 20; ++seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    const auto uniform = [&](double a, double b) { return a + (b - a) * unit(rng); };
    std::map<uint64_t, Pose2> node_pose;
    std::vector<TestKeyframe> keyframes;  // key = index
    Placed placed;
    KeyframeMoves moves(kTolerance);
    for (int step = 0; step < 60; ++step) {
      // Moves: a few nodes far, many by a fraction of the tolerance, the rest not at all.
      for (auto& [node, pose] : node_pose) {
        const double r = unit(rng);
        double scale = 0.0;
        if (r < 0.05) {
          scale = 0.5;
        } else if (r < 0.5) {
          scale = 0.002;
        }
        pose = Pose2(pose.x() + scale * uniform(-1, 1), pose.y() + scale * uniform(-1, 1),
                     WrapAngle(pose.theta() + 0.1 * scale * uniform(-1, 1)));
      }
      // A restart: every keyframe again, all placed.
      const bool restart = unit(rng) < 0.05;
      if (restart) {
        moves.Clear();
        for (size_t k = 0; k < keyframes.size(); ++k) {
          moves.Add(k, k, keyframes[k].node, keyframes[k].offset, Lever(keyframes[k]), true);
        }
      }
      // New keyframes: on new nodes (their own variable) or folded onto old ones.
      const int added = static_cast<int>(uniform(0, 8));
      std::vector<uint64_t> inserted;
      for (int a = 0; a < added; ++a) {
        TestKeyframe k;
        if (node_pose.empty() || unit(rng) < 0.3) {
          k.node = 1000 + node_pose.size();
          node_pose[k.node] = Pose2(uniform(-50, 50), uniform(-50, 50), uniform(-3, 3));
        } else {
          auto it = node_pose.begin();
          std::advance(it, static_cast<long>(uniform(0, static_cast<double>(node_pose.size()))));
          k.node = it->first;
          k.offset = Pose2(uniform(-1, 1), uniform(-1, 1), uniform(-0.5, 0.5));
        }
        k.reach = uniform(0.0, 10.0);
        const uint64_t key = keyframes.size();
        keyframes.push_back(k);
        moves.Add(key, key, k.node, k.offset, Lever(k), false);
        inserted.push_back(key);
      }
      const bool all = unit(rng) < 0.1;
      KeyframeMoves::Pass pass = moves.Examine(
          [&](uint64_t node) { return node_pose.at(node); },
          [&](uint64_t key, const Pose2& pose) { return placed.Displacement(key, pose); }, all);
      examined += pass.nodes_examined;
      skipped += static_cast<int64_t>(node_pose.size()) - pass.nodes_examined;
      // The scan of every keyframe.
      std::map<uint64_t, std::pair<double, Pose2>> expected_moved;
      size_t expected_unchanged = 0;
      for (size_t key = 0; key < keyframes.size(); ++key) {
        const TestKeyframe& k = keyframes[key];
        const Pose2 pose =
            k.offset ? Compose(node_pose.at(k.node), *k.offset) : node_pose.at(k.node);
        const std::optional<double> d = placed.Displacement(key, pose);
        if (!d) continue;
        if (*d > kTolerance) {
          expected_moved[key] = {*d, pose};
        } else {
          ++expected_unchanged;
        }
      }
      ASSERT_EQ(pass.moved.size(), expected_moved.size()) << "seed " << seed << " step " << step;
      found += static_cast<int64_t>(pass.moved.size());
      for (const KeyframeMoves::Found& f : pass.moved) {
        ASSERT_EQ(expected_moved.count(f.key), 1u);
        EXPECT_EQ(f.displacement, expected_moved[f.key].first);
        EXPECT_EQ(f.pose.x(), expected_moved[f.key].second.x());
        EXPECT_EQ(f.pose.theta(), expected_moved[f.key].second.theta());
      }
      if (all) {
        EXPECT_EQ(pass.unchanged.size(), expected_unchanged);
      }
      ASSERT_EQ(pass.inserted.size(), inserted.size());
      for (size_t i = 0; i < inserted.size(); ++i) {
        const KeyframeMoves::Found& f = pass.inserted[i];
        ASSERT_EQ(f.key, inserted[i]);
        const TestKeyframe& k = keyframes[f.key];
        const Pose2 pose =
            k.offset ? Compose(node_pose.at(k.node), *k.offset) : node_pose.at(k.node);
        EXPECT_EQ(f.pose.x(), pose.x());
        placed.pose[f.key] = f.pose;
        placed.reach[f.key] = k.reach;
      }
      // A budget: the farthest placed again, the others deferred.
      std::sort(pass.moved.begin(), pass.moved.end(),
                [](const auto& a, const auto& b) { return a.displacement > b.displacement; });
      const auto take = std::min(pass.moved.size(), static_cast<size_t>(uniform(0, 12)));
      for (size_t n = 0; n < take; ++n) placed.pose[pass.moved[n].key] = pass.moved[n].pose;
      moves.Settle({pass.moved.begin() + static_cast<long>(take), pass.moved.end()});
    }
  }
  // Moves were found, and most nodes were not looked into.
  EXPECT_GT(found, 1000);
  EXPECT_GT(skipped, examined);
}

// A keyframe that is its own node (no offset) moves as the node does: the same pose bits.
TEST(KeyframeMovesTest, AKeyframeWithoutOffsetIsItsNode) {
  KeyframeMoves moves(0.05);
  Placed placed;
  moves.Add(7, 0, 70, std::nullopt, 5.0, false);
  Pose2 node(1.0, 2.0, 0.3);
  KeyframeMoves::Pass pass = moves.Examine(
      [&](uint64_t) { return node; },
      [&](uint64_t key, const Pose2& pose) { return placed.Displacement(key, pose); });
  ASSERT_EQ(pass.inserted.size(), 1u);
  EXPECT_EQ(pass.inserted[0].pose.x(), 1.0);
  placed.pose[7] = node;
  placed.reach[7] = 5.0;
  moves.Settle({});
  node = Pose2(1.0, 2.0, 0.3 + 0.02);  // 0.1 m at the scan's reach: past 0.05
  pass = moves.Examine(
      [&](uint64_t) { return node; },
      [&](uint64_t key, const Pose2& pose) { return placed.Displacement(key, pose); });
  ASSERT_EQ(pass.moved.size(), 1u);
  EXPECT_NEAR(pass.moved[0].displacement, 0.1, 1e-12);
}

}  // namespace
}  // namespace anchormap
