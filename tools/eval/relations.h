#pragma once
// The relations metric of Kümmerle, Steder, Dornhege, Ruhnke, Grisetti, Stachniss and Kleiner,
// "On measuring the accuracy of SLAM algorithms", Autonomous Robots 27(4), 2009, as their
// metricEvaluator computes it (../shared/data/SOURCES.md). A .relations file lists reference
// relative poses "t1 t2 x y z roll pitch yaw": the robot at time t2 seen from its frame at t1.
// For each relation the estimated poses nearest in time to t1 and t2 give the estimated
// relative pose X(t1)^-1 X(t2); the translational error is the norm of the difference of the
// two translations (metres), the rotational error the absolute wrapped difference of the yaws
// (radians). Relations that cannot be evaluated are skipped and counted by reason.

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "common/types/stamped_pose2.h"
#include "common/util/status.h"
#include "tools/eval/error_stats.h"

namespace anchormap {

struct Relation {
  double t1_s = 0.0;
  double t2_s = 0.0;
  Pose2 T_1_2;  // reference pose at t2 in the frame at t1 (z, roll and pitch are dropped)
};

// Parses "t1 t2 x y z roll pitch yaw"; errors say which field and why.
Status ParseRelationLine(std::string_view line, Relation* relation);

// Reads a whole file ('#' comments and blank lines skipped); errors are "PATH:LINE: reason".
Status ReadRelationsFile(const std::string& path, std::vector<Relation>* relations);

struct RelationsOptions {
  // An estimated pose counts as "at" t1 (or t2) when it is at most this far away in time.
  // Keyframes sit exactly at scan times, which is where the benchmark's relations are, so a
  // tolerance below the scan period (0.1-0.2 s in the benchmark logs) evaluates the relations
  // whose scans became keyframes and skips the others instead of comparing a nearby pose.
  double max_time_gap_s = 0.05;

  Status Validate() const;
};

// The estimate the relations are evaluated on: poses sorted by time, and for each pose the id
// of the frame it is expressed in (poses in different frames cannot be compared: an
// unanchored trajectory, or two groups of trajectories not yet joined). Empty frame_ids means
// one frame for all.
struct RelationsEstimate {
  StampedTrajectory poses;
  std::vector<int> frame_ids;
};

struct RelationsResult {
  int64_t relations = 0;              // given
  int64_t evaluated = 0;              // = translation_m.count
  int64_t skipped_outside_span = 0;   // t1 or t2 outside [first, last] estimate time +- tolerance
  int64_t skipped_no_pose_near = 0;   // inside the span but no estimated pose within tolerance
  int64_t skipped_across_frames = 0;  // the two poses are in different frames
  ErrorStats translation_m;
  ErrorStats rotation_rad;
  double translation_sq_mean_m2 = 0.0;  // the paper's squared-error variant
  double rotation_sq_mean_rad2 = 0.0;
};

// One evaluated relation's errors, to find where in a run the error comes from.
struct RelationError {
  double t1_s = 0.0;
  double t2_s = 0.0;
  double distance_m = 0.0;  // the reference relation's length
  double translation_m = 0.0;
  double rotation_rad = 0.0;
};

// Evaluates every relation once. Costs O(r log n) for r relations and n poses.
// With `per_relation`, each evaluated relation's errors are appended to it, in input order.
RelationsResult EvaluateRelations(const std::vector<Relation>& relations,
                                  const RelationsEstimate& estimate,
                                  const RelationsOptions& options,
                                  std::vector<RelationError>* per_relation = nullptr);

}  // namespace anchormap
