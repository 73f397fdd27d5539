// Runs the anchormap-sim executable: flags, exit codes, and a short simulation.

#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>
#include "tests/testing/scratch.h"

namespace {

int RunSim(const std::string& arguments) {
  const std::string command =
      std::string(ANCHORMAP_BINARY_DIR) + "/bin/anchormap-sim " + arguments + " > /dev/null 2>&1";
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(SimMainTest, HelpAndBadFlags) {
  EXPECT_EQ(RunSim("--help"), 0);
  EXPECT_EQ(RunSim("--no-such-flag"), 2);
  EXPECT_EQ(RunSim("--robots 3"), 2);  // no --output
  EXPECT_EQ(RunSim("--robots 0 --output /tmp/x.lcmlog"), 2);
  EXPECT_EQ(RunSim("--robots three --output /tmp/x.lcmlog"), 2);
  EXPECT_EQ(RunSim("--fov-deg 400 --output /tmp/x.lcmlog"), 2);
  EXPECT_EQ(RunSim("--laser-rate-hz 7 --output /tmp/x.lcmlog"), 2);  // 50 Hz is no multiple of 7
}

TEST(SimMainTest, WritesALogAndAPreview) {
  const std::filesystem::path dir = ::anchormap::testing::ScratchDir() / "sim_main_test";
  std::filesystem::create_directories(dir);
  const std::string log = (dir / "sim.lcmlog").string();
  const std::string png = (dir / "preview.png").string();
  std::filesystem::remove(log);
  ASSERT_EQ(RunSim("--robots 2 --seed 5 --duration-s 5 --output " + log + " --preview-png " + png),
            0);
  EXPECT_GT(std::filesystem::file_size(log), 100000u);
  EXPECT_GT(std::filesystem::file_size(png), 1000u);
  EXPECT_EQ(RunSim("--robots 2 --duration-s 1 --world /nonexistent.pgm --output " + log), 1);
}

}  // namespace
