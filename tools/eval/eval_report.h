#pragma once
// What anchormap-eval prints: a readable table, or one JSON object (--json) for scripts.

#include <string>
#include <vector>

#include "tools/eval/relations.h"
#include "tools/eval/trajectory_error.h"

namespace anchormap {

// ATE / RPE of one trajectory, or of the merged map (several trajectories, one alignment).
struct TrajectoryReport {
  std::string label;                 // "R1", "R1#7" when a robot has several trajectories, "merged"
  std::vector<std::string> members;  // the trajectories' labels (merged: all of the group)
  bool anchored = false;
  int group = -1;
  int64_t poses = 0;      // estimated poses
  int64_t unmatched = 0;  // estimated poses without a reference pose close enough in time
  std::string reference;  // the reference channel or file ("" when none: not evaluated)
  TrajectoryError error;
};

struct AteReport {
  std::string map_path;
  std::string truth_path;
  int64_t map_update = -1;
  int num_groups = 0;
  double max_time_gap_s = 0.0;
  std::vector<TrajectoryReport> trajectories;
  bool has_merged = false;
  TrajectoryReport merged;
};

struct RelationsReport {
  std::string relations_path;
  std::string map_path;
  std::string robot;  // "" = all trajectories
  int64_t map_update = -1;
  int64_t estimate_poses = 0;
  double max_time_gap_s = 0.0;
  std::string odometry_path;       // "" = keyframes only
  int completed_trajectories = 0;  // trajectories completed with odometry
  int64_t time_repaired_ends = 0;  // relation ends moved to a re-timed scan (clock_shift.h)
  RelationsResult result;
};

std::string FormatAteTable(const AteReport& report);
std::string FormatAteJson(const AteReport& report);
std::string FormatRelationsTable(const RelationsReport& report);
std::string FormatRelationsJson(const RelationsReport& report);

// `text` as a JSON string literal (quotes and escapes included).
std::string JsonString(const std::string& text);

}  // namespace anchormap
