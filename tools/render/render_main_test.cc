// Runs the anchormap-render executable on a synthetic server log.

#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>

#include <gtest/gtest.h>

#include "tests/testing/scratch.h"
#include "tools/render/testing_helpers.h"

namespace anchormap::render {
namespace {

int RunRender(const std::string& arguments) {
  const std::string command = std::string(ANCHORMAP_BINARY_DIR) + "/bin/anchormap-render " +
                              arguments + " > /dev/null 2>&1";
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(RenderMainTest, WritesEveryOutput) {
  const std::filesystem::path dir = ::anchormap::testing::ScratchDir() / "render_main_test";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string log = (dir / "run.lcmlog").string();
  ASSERT_TRUE(testing::WriteTestServerLog(log).ok());
  ASSERT_EQ(RunRender("--map " + log + " --png " + (dir / "map.png").string() + " --pgm " +
                      (dir / "map.pgm").string() + " --g2o " + (dir / "merged.g2o").string() +
                      " --uncertainty-png " + (dir / "anchors.png").string()),
            0);
  testing::DecodedPng map;
  ASSERT_TRUE(testing::DecodePng((dir / "map.png").string(), &map));
  EXPECT_EQ(map.width, 1400);
  EXPECT_TRUE(std::filesystem::exists(dir / "map.yaml"));
  EXPECT_EQ(std::filesystem::file_size(dir / "map.pgm"),
            std::string("P5\n20 20\n255\n").size() + 400);
  EXPECT_GT(std::filesystem::file_size(dir / "merged.g2o"), 100u);
  testing::DecodedPng plot;
  EXPECT_TRUE(testing::DecodePng((dir / "anchors.png").string(), &plot));
}

TEST(RenderMainTest, ExitCodes) {
  EXPECT_EQ(RunRender("--help"), 0);
  EXPECT_EQ(RunRender("--bogus"), 2);
  EXPECT_EQ(RunRender("--png x.png"), 2);     // no --map
  EXPECT_EQ(RunRender("--map x.lcmlog"), 2);  // nothing to write
  EXPECT_EQ(RunRender("--map x.lcmlog --png x.png --pixels-per-m -1"), 2);
  EXPECT_EQ(RunRender("--map /nonexistent.lcmlog --png /tmp/x.png"), 1);
}

TEST(RenderMainTest, PgmWithoutGridFailsButPngIsStillWritten) {
  const std::filesystem::path dir = ::anchormap::testing::ScratchDir() / "render_main_nogrid";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string log = (dir / "run.lcmlog").string();
  {
    LcmLogWriter writer;
    ASSERT_TRUE(writer.Open(log).ok());
    EXPECT_TRUE(writer.Write("ANCHORMAP_MERGED_MAP", 1, testing::TestMergedMap(1)).ok());
  }
  EXPECT_EQ(RunRender("--map " + log + " --png " + (dir / "map.png").string() + " --pgm " +
                      (dir / "map.pgm").string()),
            1);
  EXPECT_TRUE(std::filesystem::exists(dir / "map.png"));
  EXPECT_FALSE(std::filesystem::exists(dir / "map.pgm"));
}

}  // namespace
}  // namespace anchormap::render
