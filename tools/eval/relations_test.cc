#include "tools/eval/relations.h"

#include <cmath>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "tests/testing/data_path.h"
#include "tests/testing/scratch.h"

namespace anchormap {
namespace {

TEST(RelationsFileTest, ParsesLinesAndReportsErrors) {
  Relation relation;
  ASSERT_TRUE(ParseRelationLine("976052905.167303 976052911.885496 -0.056990 -0.128430 0.000000 "
                                "0.000000 0.000000 -1.682210",
                                &relation)
                  .ok());
  EXPECT_EQ(relation.t1_s, 976052905.167303);
  EXPECT_EQ(relation.t2_s, 976052911.885496);
  EXPECT_EQ(relation.T_1_2.x(), -0.05699);
  EXPECT_EQ(relation.T_1_2.y(), -0.12843);
  EXPECT_EQ(relation.T_1_2.theta(), -1.68221);
  EXPECT_EQ(ParseRelationLine("1 2 3", &relation).message(),
            "expected 8 fields (t1 t2 x y z roll pitch yaw), found 3");
  EXPECT_EQ(ParseRelationLine("1 2 3 0 0 0 0 yaw", &relation).message(),
            "field yaw 'yaw' is not a finite number");

  const std::string path = ::anchormap::testing::ScratchPath("am_relations_test.relations");
  std::ofstream(path) << "# comment\n1 2 0 0 0 0 0 0\n\n1 2 0 0 0 0 0\n";
  std::vector<Relation> relations;
  EXPECT_EQ(ReadRelationsFile(path, &relations).message(),
            path + ":4: expected 8 fields (t1 t2 x y z roll pitch yaw), found 7");
  std::filesystem::remove(path);
}

// The tiny case, by hand. Estimated poses (t in seconds: x, y, theta):
//   t=1: (0, 0, 0)   t=2: (1, 0, 0)   t=3: (1, 1, 3.0)   t=4: (5, 5, 0) in another frame
// Estimated relative poses X(t1)^-1 X(t2):
//   (1,2): (1, 0, 0)       (2,3): (0, 1, 3.0)       (1,3): (1, 1, 3.0)
// Reference relations and errors:
//   (1,2) ref (1.1, 0, 0.1):            translation |(1,0)-(1.1,0)| = 0.1, rotation 0.1
//   (2,3) ref (0, 1.3, 3.2 - 2 pi):     translation 0.3, rotation |wrap(3.0 - 3.2 + 2 pi)| = 0.2
//   (1,3) ref (1, 1.5, 2.7):            translation 0.5, rotation 0.3
// Translation: mean 0.3, sample std sqrt((0.04 + 0 + 0.04) / 2) = 0.2, min 0.1, max 0.5,
//   mean of squares (0.01 + 0.09 + 0.25) / 3 = 0.35 / 3.
// Rotation: mean 0.2, sample std sqrt((0.01 + 0 + 0.01) / 2) = 0.1, min 0.1, max 0.3.
// Skipped: (0.5, 2) starts before the estimate; (1, 2.5) has no pose within 0.05 s of 2.5;
//   (3, 4) joins two frames; (3.96, 9) ends after it.
TEST(EvaluateRelationsTest, HandComputedTinyCase) {
  RelationsEstimate estimate;
  estimate.poses = {{1000000, Pose2(0, 0, 0)},
                    {2000000, Pose2(1, 0, 0)},
                    {3000000, Pose2(1, 1, 3.0)},
                    {4000000, Pose2(5, 5, 0)}};
  estimate.frame_ids = {0, 0, 0, 1};
  const std::vector<Relation> relations = {
      {1.0, 2.0, Pose2(1.1, 0.0, 0.1)}, {2.0, 3.0, Pose2(0.0, 1.3, 3.2 - 2 * M_PI)},
      {1.0, 3.0, Pose2(1.0, 1.5, 2.7)}, {0.5, 2.0, Pose2(0, 0, 0)},
      {1.0, 2.5, Pose2(0, 0, 0)},       {3.0, 4.0, Pose2(0, 0, 0)},
      {3.96, 9.0, Pose2(0, 0, 0)},
  };
  // Times 0.04 s off still match the default 0.05 s tolerance.
  std::vector<Relation> shifted = relations;
  shifted[0].t1_s = 1.04;
  std::vector<RelationError> per_relation;
  const RelationsResult r = EvaluateRelations(shifted, estimate, RelationsOptions(), &per_relation);
  // Each evaluated relation's own errors, in input order: (1,2) 0.1 m, (2,3) 0.3 m, (1,3) 0.5 m.
  ASSERT_EQ(per_relation.size(), 3u);
  EXPECT_DOUBLE_EQ(per_relation[0].t1_s, 1.04);
  EXPECT_NEAR(per_relation[0].distance_m, 1.1, 1e-12);
  EXPECT_NEAR(per_relation[0].translation_m, 0.1, 1e-12);
  EXPECT_NEAR(per_relation[1].translation_m, 0.3, 1e-12);
  EXPECT_NEAR(per_relation[2].t2_s, 3.0, 1e-12);
  EXPECT_NEAR(per_relation[2].translation_m, 0.5, 1e-12);
  EXPECT_NEAR(
      per_relation[0].rotation_rad + per_relation[1].rotation_rad + per_relation[2].rotation_rad,
      0.6, 1e-12);
  EXPECT_EQ(r.relations, 7);
  EXPECT_EQ(r.evaluated, 3);
  EXPECT_EQ(r.skipped_outside_span, 2);
  EXPECT_EQ(r.skipped_no_pose_near, 1);
  EXPECT_EQ(r.skipped_across_frames, 1);
  EXPECT_NEAR(r.translation_m.mean, 0.3, 1e-12);
  EXPECT_NEAR(r.translation_m.std, 0.2, 1e-12);
  EXPECT_NEAR(r.translation_m.min, 0.1, 1e-12);
  EXPECT_NEAR(r.translation_m.max, 0.5, 1e-12);
  EXPECT_NEAR(r.translation_sq_mean_m2, 0.35 / 3, 1e-12);
  EXPECT_NEAR(r.rotation_rad.mean, 0.2, 1e-12);
  EXPECT_NEAR(r.rotation_rad.std, 0.1, 1e-12);
  EXPECT_NEAR(r.rotation_rad.min, 0.1, 1e-12);
  EXPECT_NEAR(r.rotation_rad.max, 0.3, 1e-12);

  // A tighter tolerance loses the shifted relation; without frame ids (3, 4) is evaluated.
  RelationsOptions tight;
  tight.max_time_gap_s = 0.01;
  EXPECT_EQ(EvaluateRelations(shifted, estimate, tight).evaluated, 2);
  estimate.frame_ids.clear();
  EXPECT_EQ(EvaluateRelations(relations, estimate, RelationsOptions()).evaluated, 4);
}

TEST(EvaluateRelationsTest, EmptyEstimateSkipsEverything) {
  const RelationsResult r =
      EvaluateRelations({{1.0, 2.0, Pose2()}}, RelationsEstimate(), RelationsOptions());
  EXPECT_EQ(r.evaluated, 0);
  EXPECT_EQ(r.skipped_outside_span, 1);
}

struct RealRelations {
  const char* file;
  int64_t count;
};
void PrintTo(const RealRelations& r, std::ostream* os) { *os << r.file; }
class RealRelationsTest : public ::testing::TestWithParam<RealRelations> {};

TEST_P(RealRelationsTest, ReadsEveryLine) {
  ANCHORMAP_REQUIRE_DATA(path, GetParam().file);
  std::vector<Relation> relations;
  ASSERT_TRUE(ReadRelationsFile(path, &relations).ok());
  EXPECT_EQ(static_cast<int64_t>(relations.size()), GetParam().count);
}

INSTANTIATE_TEST_SUITE_P(SharedData, RealRelationsTest,
                         ::testing::Values(RealRelations{"benchmark/intel.relations", 2984},
                                           RealRelations{"benchmark/aces.relations", 1279},
                                           RealRelations{"benchmark/fr079.relations", 1685}));

}  // namespace
}  // namespace anchormap
