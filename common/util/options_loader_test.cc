#include "common/util/options_loader.h"
#include "tests/testing/scratch.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

struct DemoOptions {
  double max_distance_m = 0.5;
  int max_keyframes = 10;
  int64_t trajectory_id = 0;
  bool verbose = false;
  std::string robot;
};

class OptionsLoaderTest : public ::testing::Test {
 protected:
  OptionsLoaderTest() : loader_("demo", "[options]", "A demo.") {
    loader_.Add("keyframer.max_distance_m", "keyframe-distance-m", &options_.max_distance_m,
                "distance between keyframes");
    loader_.Add("keyframer.max_keyframes", "", &options_.max_keyframes, "a count");
    loader_.Add("trajectory_id", "", &options_.trajectory_id, "an id");
    loader_.Add("verbose", "", &options_.verbose, "talk more");
    loader_.Add("robot", "", &options_.robot, "robot name", /*required=*/true);
  }

  ParseOutcome Run(std::vector<std::string> args) {
    args.insert(args.begin(), "demo");
    std::vector<const char*> argv;
    for (const auto& a : args) argv.push_back(a.c_str());
    ::testing::internal::CaptureStderr();
    ::testing::internal::CaptureStdout();
    ParseOutcome outcome = loader_.Parse(static_cast<int>(argv.size()), argv.data());
    stderr_ = ::testing::internal::GetCapturedStderr();
    stdout_ = ::testing::internal::GetCapturedStdout();
    return outcome;
  }

  std::string WriteConfig(const std::string& text) {
    const auto path =
        ::anchormap::testing::ScratchDir() / ("options_" + std::to_string(files_.size()) + ".cfg");
    std::ofstream(path) << text;
    files_.push_back(path.string());
    return path.string();
  }

  void TearDown() override {
    for (const auto& f : files_) std::filesystem::remove(f);
  }

  DemoOptions options_;
  OptionsLoader loader_;
  std::string stderr_, stdout_;
  std::vector<std::string> files_;
};

TEST_F(OptionsLoaderTest, FlagsSetFields) {
  const auto outcome =
      Run({"--robot", "R2", "--keyframe-distance-m", "1.25", "--keyframer-max-keyframes=7",
           "--trajectory-id", "1700000000000000", "--verbose"});
  ASSERT_TRUE(outcome.run) << stderr_;
  EXPECT_EQ(options_.robot, "R2");
  EXPECT_DOUBLE_EQ(options_.max_distance_m, 1.25);
  EXPECT_EQ(options_.max_keyframes, 7);
  EXPECT_EQ(options_.trajectory_id, 1700000000000000);
  EXPECT_TRUE(options_.verbose);
  EXPECT_TRUE(loader_.WasSet("keyframer.max_distance_m"));
  EXPECT_FALSE(loader_.WasSet("nonexistent"));
}

TEST_F(OptionsLoaderTest, ConfigFileWithSectionsAndFlagsOverrideIt) {
  const std::string path =
      WriteConfig("# comment\nrobot = R3\n[keyframer]\nmax_distance_m = 2.5\nmax_keyframes = 4\n");
  const auto outcome = Run({"--config", path, "--keyframer-max-keyframes", "9"});
  ASSERT_TRUE(outcome.run) << stderr_;
  EXPECT_EQ(options_.robot, "R3");
  EXPECT_DOUBLE_EQ(options_.max_distance_m, 2.5);
  EXPECT_EQ(options_.max_keyframes, 9);  // flag wins over the file
}

TEST_F(OptionsLoaderTest, UnknownConfigKeyIsRefusedWithItsName) {
  const std::string path = WriteConfig("robot = R1\n[keyframer]\nmax_distanse_m = 2\n");
  const auto outcome = Run({"--config", path});
  EXPECT_FALSE(outcome.run);
  EXPECT_EQ(outcome.exit_code, 2);
  EXPECT_NE(outcome.error.message().find("keyframer.max_distanse_m"), std::string::npos)
      << outcome.error.message();
  EXPECT_NE(stderr_.find("keyframer.max_distanse_m"), std::string::npos);
}

TEST_F(OptionsLoaderTest, UnknownFlagMalformedValueAndPositionalAreUsageErrors) {
  auto outcome = Run({"--robot", "R1", "--keyframe-distanse-m", "1"});
  EXPECT_EQ(outcome.exit_code, 2);
  EXPECT_NE(outcome.error.message().find("keyframe-distanse-m"), std::string::npos)
      << outcome.error.message();

  outcome = Run({"--robot", "R1", "--keyframe-distance-m", "1.5x"});
  EXPECT_EQ(outcome.exit_code, 2);
  EXPECT_NE(outcome.error.message().find("--keyframe-distance-m"), std::string::npos)
      << outcome.error.message();

  outcome = Run({"--robot", "R1", "--keyframe-distance-m", "nan"});
  EXPECT_EQ(outcome.exit_code, 2);

  outcome = Run({"--robot", "R1", "--keyframer-max-keyframes", "99999999999"});
  EXPECT_EQ(outcome.exit_code, 2);

  outcome = Run({"--robot", "R1", "stray"});
  EXPECT_EQ(outcome.exit_code, 2);
  EXPECT_FALSE(outcome.run);
}

TEST_F(OptionsLoaderTest, MissingRequiredOptionIsAUsageError) {
  const auto outcome = Run({"--verbose", "false"});
  EXPECT_FALSE(outcome.run);
  EXPECT_EQ(outcome.exit_code, 2);
  EXPECT_NE(outcome.error.message().find("--robot"), std::string::npos) << outcome.error.message();
  EXPECT_FALSE(options_.verbose);
}

TEST_F(OptionsLoaderTest, HelpListsEveryOptionWithDefaultAndKey) {
  const auto outcome = Run({"--help"});
  EXPECT_FALSE(outcome.run);
  EXPECT_EQ(outcome.exit_code, 0);
  EXPECT_NE(stdout_.find("--keyframe-distance-m <number> (default: 0.5)"), std::string::npos)
      << stdout_;
  EXPECT_NE(stdout_.find("[config key: keyframer.max_distance_m]"), std::string::npos);
  EXPECT_NE(stdout_.find("--robot <text> (required)"), std::string::npos);
}

TEST_F(OptionsLoaderTest, EffectiveConfigAndMarkdownComeFromTheSameList) {
  ASSERT_TRUE(Run({"--robot", "R1", "--keyframe-distance-m", "0.75"}).run);
  const std::string config = loader_.EffectiveConfig();
  EXPECT_NE(config.find("keyframer.max_distance_m = 0.75\n"), std::string::npos) << config;
  EXPECT_NE(config.find("robot = R1\n"), std::string::npos);
  const std::string table = loader_.MarkdownTable();
  EXPECT_NE(table.find("| `--keyframe-distance-m` | `keyframer.max_distance_m` | `0.5` |"),
            std::string::npos)
      << table;
}

TEST_F(OptionsLoaderTest, BooleansAndNumbersAreStrict) {
  EXPECT_TRUE(Run({"--robot", "R1", "--verbose", "on"}).run);
  EXPECT_TRUE(options_.verbose);
  EXPECT_TRUE(Run({"--robot", "R1", "--verbose", "off"}).run);
  EXPECT_FALSE(options_.verbose);
  const ParseOutcome maybe = Run({"--robot", "R1", "--verbose", "maybe"});
  EXPECT_FALSE(maybe.run);
  EXPECT_EQ(maybe.exit_code, 2);
  EXPECT_NE(maybe.error.message().find("'maybe' is not true/false"), std::string::npos);
  EXPECT_FALSE(Run({"--robot", "R1", "--keyframe-distance-m", "inf"}).run);
  EXPECT_FALSE(Run({"--robot", "R1", "--keyframer-max-keyframes", "3000000000"}).run);
}

TEST(FormatDoubleTest, ShortestUsefulText) { EXPECT_EQ(FormatDouble(0.001), "0.001"); }

}  // namespace
}  // namespace anchormap
