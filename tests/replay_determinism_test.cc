// The offline path is deterministic (issue 11): two `anchormap-replay` runs of one recorded
// simulation, with the agents' scan matching and the server's loop closures and scan
// encounters on, write the same bytes, status messages included; with the daemons' defaults
// (the reduced graph) and with the full graph. The matching runs on worker
// threads online; offline it must give the same result whatever the scheduling.

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/types/constraint_kind.h"
#include "tests/merged_map_log.h"
#include "tests/testing/file_contents.h"
#include "tests/testing/scratch.h"
#include "tests/testing/tool_run.h"

namespace anchormap {
namespace {

using ::anchormap::testing::FileContents;
using ::anchormap::testing::ServerStatusLine;

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
  // The daemons' defaults (the reduced graph, the solve period), and the full graph with one
  // update per input.
  const std::vector<std::string> variants = {"", " --reduced-graph false --solve-period-s 0"};
  for (size_t v = 0; v < variants.size(); ++v) {
    for (const char* run : {"1", "2"}) {
      const std::string stem = "v" + std::to_string(v) + "_" + run;
      const std::string replay = bin + "anchormap-replay --log " + (dir / "sim.lcmlog").string() +
                                 " --output " + (dir / (stem + ".lcmlog")).string() +
                                 " --log-level info" + variants[v] + " 2> " +
                                 (dir / (stem + ".txt")).string();
      ASSERT_EQ(std::system(replay.c_str()), 0) << replay;
    }
    const std::string first = FileContents(dir / ("v" + std::to_string(v) + "_1.lcmlog"));
    ASSERT_GT(first.size(), 10000u);
    EXPECT_TRUE(first == FileContents(dir / ("v" + std::to_string(v) + "_2.lcmlog")))
        << "the two replays' outputs differ (" << variants[v] << ")";
  }

  // The runs exercised what must be deterministic: both robots in one frame, joined by scan
  // encounters; with the defaults keyframes folded, with the full graph loop closures.
  const std::string status = ServerStatusLine(FileContents(dir / "v0_1.txt"));
  std::printf("%s\n", status.c_str());
  const size_t folded_at = status.find(" folded ");
  ASSERT_NE(folded_at, std::string::npos) << status;
  EXPECT_GT(std::atoi(status.c_str() + folded_at + 8), 0) << status;
  for (const char* output : {"v0_1.lcmlog", "v1_1.lcmlog"}) {
    SCOPED_TRACE(output);
    const Result<MergedMap> last = LastMergedMapInLog((dir / output).string());
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
    if (std::string(output) == "v1_1.lcmlog") {
      EXPECT_GT(loop_closures, 0);
    }
    EXPECT_GT(scan_encounters, 0);
  }
}

}  // namespace
}  // namespace anchormap
