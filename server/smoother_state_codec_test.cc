// The smoother's state codec: from version 8 the factors since the last correction are
// written (the skip test sums their gradient); in an older format there is no room for
// them, so the skip test's bound is written as infinite when there are any (the restored
// smoother corrects at its next update instead of skipping on a bound that leaves them out).

#include "server/smoother_state_codec.h"

#include <cmath>
#include <cstdint>
#include <vector>

#include <gtest/gtest.h>

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

}  // namespace
}  // namespace anchormap
