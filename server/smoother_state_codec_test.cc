// The smoother's state codec: from version 8 the factors since the last correction are
// written (the skip test sums their gradient); in an older format there is no room for
// them, so the skip test's bound is written as infinite when there are any (the restored
// smoother corrects at its next update instead of skipping on a bound that leaves them out).

#include "server/smoother_state_codec.h"

#include <cmath>
#include <cstdint>
#include <vector>

#include <gtest/gtest.h>

#include "common/geometry/pose2.h"
#include "server/snapshot_codec.h"

namespace anchormap {
namespace {

SmootherState Decode(const std::vector<uint8_t>& bytes, uint32_t version, bool* complete) {
  ByteReader r(bytes.data(), bytes.size());
  SmootherState state;
  GetSmootherState(&r, version, &state);
  *complete = !r.failed() && r.at_end();
  return state;
}

std::vector<uint8_t> Encode(const SmootherState& state, uint32_t version) {
  ByteWriter w;
  PutSmootherState(&w, version, state);
  return w.Take();
}

TEST(SmootherStateCodecTest, TheUncorrectedFactorsAreKeptOrTheirBoundIsInfinite) {
  SmootherState state;
  state.correction_converged = true;
  state.innovation = 0.25;
  state.uncorrected_factors = {12, 13, 40};
  bool complete = false;
  SmootherState out = Decode(Encode(state, kSnapshotVersion), kSnapshotVersion, &complete);
  EXPECT_TRUE(complete);
  EXPECT_EQ(out.innovation, 0.25);
  EXPECT_EQ(out.uncorrected_factors, state.uncorrected_factors);

  out = Decode(Encode(state, 7), 7, &complete);
  EXPECT_TRUE(complete);
  EXPECT_TRUE(std::isinf(out.innovation));
  EXPECT_TRUE(out.uncorrected_factors.empty());

  // None to leave out: the bound as it is.
  state.uncorrected_factors.clear();
  out = Decode(Encode(state, 7), 7, &complete);
  EXPECT_TRUE(complete);
  EXPECT_EQ(out.innovation, 0.25);
}

// From version 11 the local corrections' moves are written (the skip test adds the moved
// factors' change since the last pass); an older format has no room for them and writes the
// bound as infinite when there are any.
TEST(SmootherStateCodecTest, TheLocalMovesAreKeptOrTheirBoundIsInfinite) {
  SmootherState state;
  state.correction_converged = true;
  state.innovation = 0.25;
  state.uncorrected_factors = {12, 13, 40};
  state.local_pass_values = {{7, Pose2(1.5, -2.25, 0.125)}, {3, Pose2(-0.5, 4.0, -3.0)}};
  state.local_moved_factors = {2, 9};
  state.local_seeds_from = 2;
  bool complete = false;
  SmootherState out = Decode(Encode(state, kSnapshotVersion), kSnapshotVersion, &complete);
  EXPECT_TRUE(complete);
  EXPECT_EQ(out.innovation, 0.25);
  ASSERT_EQ(out.local_pass_values.size(), 2u);
  EXPECT_EQ(out.local_pass_values[0].variable, 7);
  EXPECT_EQ(out.local_pass_values[0].value.y(), -2.25);
  EXPECT_EQ(out.local_pass_values[1].variable, 3);
  EXPECT_EQ(out.local_pass_values[1].value.theta(), -3.0);
  EXPECT_EQ(out.local_moved_factors, state.local_moved_factors);
  EXPECT_EQ(out.local_seeds_from, 2);

  out = Decode(Encode(state, 10), 10, &complete);
  EXPECT_TRUE(complete);
  EXPECT_TRUE(std::isinf(out.innovation));
  EXPECT_EQ(out.uncorrected_factors, state.uncorrected_factors);
  EXPECT_TRUE(out.local_pass_values.empty());
  EXPECT_TRUE(out.local_moved_factors.empty());
  EXPECT_EQ(out.local_seeds_from, 0);

  // No local move to leave out: the bound as it is.
  state.local_pass_values.clear();
  state.local_moved_factors.clear();
  state.local_seeds_from = 0;
  out = Decode(Encode(state, 10), 10, &complete);
  EXPECT_TRUE(complete);
  EXPECT_EQ(out.innovation, 0.25);
}

}  // namespace
}  // namespace anchormap
