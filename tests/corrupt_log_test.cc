// anchormap-server --log on a corrupt LCM log: the damaged stretch is named by its byte
// offset, the events after it are still read, and the exit status is 3 (not 0).
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/bus/codec.h"
#include "common/bus/lcm_log.h"
#include "tests/testing/file_contents.h"
#include "tests/testing/scratch.h"
#include "tests/testing/straight_keyframes.h"

namespace anchormap {
namespace {

Keyframe MakeKeyframe(int32_t seq) {
  return testing::StraightKeyframe("R1", 7, seq, /*num_rays=*/21,
                                   /*first_utime=*/1'700'000'000'000'000);
}

TEST(CorruptLogTest, ServerNamesTheOffsetResynchronisesAndFails) {
  const std::filesystem::path dir = ::anchormap::testing::ScratchDir();
  std::filesystem::create_directories(dir);
  const std::filesystem::path input = dir / "in.lcmlog", output = dir / "out.lcmlog",
                              log = dir / "server.log";
  {
    LcmLogWriter writer;
    ASSERT_TRUE(writer.Open(input.string()).ok());
    for (int seq = 0; seq < 6; ++seq) {
      const std::vector<uint8_t> bytes = EncodeKeyframe(MakeKeyframe(seq));
      ASSERT_TRUE(
          writer
              .WriteRaw("ANCHORMAP_KEYFRAMES", MakeKeyframe(seq).utime, bytes.data(), bytes.size())
              .ok());
    }
  }
  std::string bytes = ::anchormap::testing::FileContents(input);
  const size_t event = bytes.size() / 6;
  bytes[2 * event + 1] = 'X';  // event 2's sync word
  {
    std::ofstream out(input, std::ios::binary | std::ios::trunc);
    out << bytes;
  }
  const std::string server = std::string(ANCHORMAP_BINARY_DIR) + "/bin/anchormap-server";
  const std::string command = server + " --log " + input.string() + " --output " + output.string() +
                              " > " + log.string() + " 2>&1";
  const int status = std::system(command.c_str());
  ASSERT_TRUE(WIFEXITED(status)) << command;
  EXPECT_EQ(WEXITSTATUS(status), 3) << ::anchormap::testing::FileContents(log);
  const std::string text = ::anchormap::testing::FileContents(log);
  EXPECT_NE(text.find("corrupt event at byte " + std::to_string(2 * event)), std::string::npos)
      << text;
  EXPECT_NE(text.find("next event at byte " + std::to_string(3 * event)), std::string::npos)
      << text;
  // Five of six keyframes were read: the ones after the damage too.
  EXPECT_NE(text.find("read 5 events"), std::string::npos) << text;
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace anchormap
