#include "server/node/mapping_server_flags.h"

#include <gtest/gtest.h>

namespace anchormap {
namespace {

ParseOutcome ParseArgs(OptionsLoader* loader, std::vector<const char*> args) {
  args.insert(args.begin(), "test");
  return loader->Parse(static_cast<int>(args.size()), args.data());
}

TEST(MappingServerFlagsTest, FlagsReachTheServersOptions) {
  MappingServerOptions options;
  OptionsLoader loader("test", "", "");
  const MappingServerFlags flags(&loader, &options);
  ASSERT_TRUE(ParseArgs(&loader, {"--formulation", "global-moved", "--correction-tolerance",
                                  "0.0002", "--loop-closures", "false", "--scan-near-distance-m",
                                  "3.5", "--map-chunk-poses", "64", "--solve-period-s", "0.25",
                                  "--correction-skip", "5"})
                  .run);
  ASSERT_TRUE(flags.Apply().ok());
  EXPECT_EQ(options.smoother.formulation, Formulation::kGlobalMoved);
  EXPECT_EQ(options.smoother.correction_tolerance, 0.0002);
  EXPECT_FALSE(options.loop_closures);
  EXPECT_EQ(options.scan.near_distance_m, 3.5);
  EXPECT_EQ(options.publish.chunks.chunk_poses, 64);
  EXPECT_EQ(options.solve_period_s, 0.25);
  EXPECT_EQ(options.smoother.correction_skip_factor, 5.0);
}

TEST(MappingServerFlagsTest, NoFlagsKeepTheDefaults) {
  MappingServerOptions options;
  options.smoother.formulation = Formulation::kGlobal;  // a caller's default survives
  const MappingServerOptions defaults = options;
  OptionsLoader loader("test", "", "");
  const MappingServerFlags flags(&loader, &options);
  ASSERT_TRUE(ParseArgs(&loader, {}).run);
  ASSERT_TRUE(flags.Apply().ok());
  EXPECT_EQ(options.smoother.formulation, Formulation::kGlobal);
  EXPECT_EQ(options.smoother.correction_tolerance, defaults.smoother.correction_tolerance);
  EXPECT_EQ(options.loop_closures, defaults.loop_closures);
  EXPECT_EQ(options.match_workers, defaults.match_workers);
}

TEST(MappingServerFlagsTest, AnUnknownFormulationIsAUsageError) {
  MappingServerOptions options;
  OptionsLoader loader("test", "", "");
  const MappingServerFlags flags(&loader, &options);
  ASSERT_TRUE(ParseArgs(&loader, {"--formulation", "absolute"}).run);
  const Status applied = flags.Apply();
  ASSERT_FALSE(applied.ok());
  EXPECT_NE(applied.message().find("'absolute'"), std::string::npos) << applied.message();
  EXPECT_EQ(options.smoother.formulation, Formulation::kRelative);
}

TEST(MappingServerFlagsTest, TheHelpPrefixStartsEveryServerOptionsHelp) {
  MappingServerOptions options;
  OptionsLoader loader("test", "", "");
  const MappingServerFlags flags(&loader, &options, "server: ");
  const std::string help = loader.HelpText();
  EXPECT_NE(help.find("server: sigma of the gauge priors"), std::string::npos) << help;
  EXPECT_EQ(help.find("  sigma of the gauge priors"), std::string::npos) << help;
}

}  // namespace
}  // namespace anchormap
