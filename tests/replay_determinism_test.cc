// The offline path is deterministic (issue 11): two `anchormap-replay` runs of one recorded
// simulation, with the agents' scan matching and the server's loop closures and scan
// encounters on, write the same bytes, status messages included. The matching runs on worker
// threads online; offline it must give the same result whatever the scheduling.

#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/types/constraint_kind.h"
#include "tests/merged_map_log.h"
#include "tests/testing/file_contents.h"
#include "tests/testing/scratch.h"

namespace anchormap {
namespace {

TEST(ReplayDeterminismTest, TwoReplaysOfOneSimulationWriteTheSameBytes) {
  const std::filesystem::path dir = ::anchormap::testing::ScratchDir();
  const std::string bin = std::string(ANCHORMAP_BINARY_DIR) + "/bin/";
  if (!std::filesystem::exists(bin + "anchormap-sim")) {
    GTEST_SKIP() << "anchormap-sim is not built (tools/sim absent)";
  }
  // Two robots for 60 s: long enough for loop closures and scan encounters (about 10 s of
  // CPU per replay in Release).
  const std::string sim = bin +
                          "anchormap-sim --robots 2 --duration-s 60 --seed 3 --quiet --output " +
                          (dir / "sim.lcmlog").string();
  ASSERT_EQ(std::system(sim.c_str()), 0) << sim;
  // The server's default solve period, and one update per input (--solve-period-s 0).
  for (const std::string period : {"", " --solve-period-s 0"}) {
    for (const char* out : {"out1.lcmlog", "out2.lcmlog"}) {
      const std::string replay = bin + "anchormap-replay --log " + (dir / "sim.lcmlog").string() +
                                 " --output " + (dir / out).string() + " --log-level warning" +
                                 period;
      ASSERT_EQ(std::system(replay.c_str()), 0) << replay;
    }
    const std::string first = ::anchormap::testing::FileContents(dir / "out1.lcmlog");
    ASSERT_GT(first.size(), 10000u);
    EXPECT_TRUE(first == ::anchormap::testing::FileContents(dir / "out2.lcmlog"))
        << "the two replays' outputs differ (" << period << ")";
  }

  // The run exercised what must be deterministic: both robots in one frame, joined by scan
  // encounters, with loop closures.
  const Result<MergedMap> last = LastMergedMapInLog((dir / "out1.lcmlog").string());
  ASSERT_TRUE(last.ok()) << last.status().message();
  const MergedMap& map = *last;
  ASSERT_EQ(map.trajectories.size(), 2u);
  for (const MergedTrajectory& trajectory : map.trajectories) EXPECT_TRUE(trajectory.anchored);
  int loop_closures = 0;
  int scan_encounters = 0;
  for (const EncounterLink& link : map.encounters) {
    loop_closures += link.kind == ConstraintKind::kLoopClosure;
    scan_encounters += link.kind == ConstraintKind::kScanEncounter;
  }
  EXPECT_GT(loop_closures, 0);
  EXPECT_GT(scan_encounters, 0);
}

}  // namespace
}  // namespace anchormap
