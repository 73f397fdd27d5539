#include "tools/eval/eval_report.h"

#include <cmath>
#include <cstdio>
#include <sstream>

namespace anchormap {
namespace {

std::string Number(double value) {
  if (!std::isfinite(value)) return "null";
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.9g", value);
  return buffer;
}

std::string StatsJson(const ErrorStats& s) {
  return "{\"count\": " + std::to_string(s.count) + ", \"mean\": " + Number(s.mean) +
         ", \"std\": " + Number(s.std) + ", \"rmse\": " + Number(s.rmse) +
         ", \"median\": " + Number(s.median) + ", \"min\": " + Number(s.min) +
         ", \"max\": " + Number(s.max) + "}";
}

std::string TrajectoryJson(const TrajectoryReport& t) {
  std::ostringstream out;
  out << "{\"label\": " << JsonString(t.label) << ", \"members\": [";
  for (size_t i = 0; i < t.members.size(); ++i) out << (i ? ", " : "") << JsonString(t.members[i]);
  out << "], \"anchored\": " << (t.anchored ? "true" : "false") << ", \"group\": " << t.group
      << ", \"poses\": " << t.poses << ", \"matched\": " << t.error.matched
      << ", \"unmatched\": " << t.unmatched
      << ", \"reference\": " << (t.reference.empty() ? "null" : JsonString(t.reference));
  const Pose2& a = t.error.T_reference_estimate;
  out << ", \"alignment\": [" << Number(a.x()) << ", " << Number(a.y()) << ", " << Number(a.theta())
      << "], \"mean_time_gap_s\": " << Number(t.error.mean_time_gap_s)
      << ", \"ate\": {\"translation_m\": " << StatsJson(t.error.ate_translation_m)
      << ", \"rotation_rad\": " << StatsJson(t.error.ate_rotation_rad)
      << "}, \"rpe\": {\"translation_m\": " << StatsJson(t.error.rpe_translation_m)
      << ", \"rotation_rad\": " << StatsJson(t.error.rpe_rotation_rad) << "}}";
  return out.str();
}

std::string TrajectoryRow(const TrajectoryReport& t) {
  char buffer[512];
  if (t.reference.empty()) {
    std::snprintf(buffer, sizeof(buffer), "%-16s %-8s %7lld  no reference poses for this robot\n",
                  t.label.c_str(), t.anchored ? "yes" : "no", (long long)t.poses);
    return buffer;
  }
  const TrajectoryError& e = t.error;
  std::snprintf(buffer, sizeof(buffer),
                "%-16s %-8s %7lld %7lld %9.4f %9.4f %9.4f %9.4f %9.4f %9.4f\n", t.label.c_str(),
                t.anchored ? "yes" : "no", (long long)t.poses, (long long)e.matched,
                e.ate_translation_m.rmse, e.ate_translation_m.mean, e.ate_translation_m.max,
                e.ate_rotation_rad.rmse, e.rpe_translation_m.rmse, e.rpe_rotation_rad.rmse);
  return buffer;
}

}  // namespace

std::string JsonString(const std::string& text) {
  std::string out = "\"";
  for (char c : text) {
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\t':
        out += "\\t";
        break;
      case '\r':
        out += "\\r";
        break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char buffer[8];
          std::snprintf(buffer, sizeof(buffer), "\\u%04x", c);
          out += buffer;
        } else {
          out += c;
        }
    }
  }
  return out + "\"";
}

std::string FormatAteTable(const AteReport& r) {
  std::ostringstream out;
  out << "anchormap-eval: estimate " << r.map_path;
  if (r.map_update >= 0) out << " (merged map update " << r.map_update << ")";
  out << ", reference " << r.truth_path << ", match within " << r.max_time_gap_s << " s\n";
  out << "ATE after a rigid alignment per row; RPE over consecutive keyframes. Metres, radians.\n";
  char header[512];
  std::snprintf(header, sizeof(header), "%-16s %-8s %7s %7s %9s %9s %9s %9s %9s %9s\n",
                "trajectory", "anchored", "poses", "matched", "ATE_rmse", "ATE_mean", "ATE_max",
                "ATErot", "RPE_rmse", "RPErot");
  out << header;
  for (const TrajectoryReport& t : r.trajectories) out << TrajectoryRow(t);
  if (r.has_merged) {
    out << TrajectoryRow(r.merged);
    out << "merged = one alignment for";
    for (const std::string& m : r.merged.members) out << " " << m;
    out << " (largest of " << r.num_groups << " anchored group" << (r.num_groups == 1 ? "" : "s")
        << ")\n";
  } else {
    out << "merged: no anchored trajectory with reference poses\n";
  }
  return out.str();
}

std::string FormatAteJson(const AteReport& r) {
  std::ostringstream out;
  out << "{\"mode\": \"ate\", \"map\": " << JsonString(r.map_path)
      << ", \"truth\": " << JsonString(r.truth_path) << ", \"map_update\": " << r.map_update
      << ", \"groups\": " << r.num_groups << ", \"max_time_gap_s\": " << Number(r.max_time_gap_s)
      << ", \"trajectories\": [";
  for (size_t i = 0; i < r.trajectories.size(); ++i) {
    out << (i ? ", " : "") << TrajectoryJson(r.trajectories[i]);
  }
  out << "], \"merged\": " << (r.has_merged ? TrajectoryJson(r.merged) : "null") << "}\n";
  return out.str();
}

std::string FormatRelationsTable(const RelationsReport& r) {
  const RelationsResult& x = r.result;
  char buffer[1024];
  std::snprintf(
      buffer, sizeof(buffer),
      "anchormap-eval: relations %s, estimate %s%s%s (%lld poses)\n"
      "relations %lld, evaluated %lld; skipped: outside the estimate's time span %lld, no "
      "estimated pose within %g s %lld, across frames %lld\n"
      "translation [m]:   mean %.4f  std %.4f  min %.4f  max %.4f  (mean of squares %.6f)\n"
      "rotation [rad]:    mean %.4f  std %.4f  min %.4f  max %.4f  (mean of squares %.6f)\n"
      "rotation [deg]:    mean %.3f  std %.3f\n",
      r.relations_path.c_str(), r.map_path.c_str(), r.robot.empty() ? "" : ", robot ",
      r.robot.c_str(), (long long)r.estimate_poses, (long long)x.relations, (long long)x.evaluated,
      (long long)x.skipped_outside_span, r.max_time_gap_s, (long long)x.skipped_no_pose_near,
      (long long)x.skipped_across_frames, x.translation_m.mean, x.translation_m.std,
      x.translation_m.min, x.translation_m.max, x.translation_sq_mean_m2, x.rotation_rad.mean,
      x.rotation_rad.std, x.rotation_rad.min, x.rotation_rad.max, x.rotation_sq_mean_rad2,
      x.rotation_rad.mean * 180.0 / M_PI, x.rotation_rad.std * 180.0 / M_PI);
  std::string text = buffer;
  if (!r.odometry_path.empty()) {
    text += "poses at the relation times: nearest keyframe + odometry motion from " +
            r.odometry_path + " (" + std::to_string(r.completed_trajectories) +
            " trajectories completed, " + std::to_string(r.time_repaired_ends) +
            " relation ends moved to re-timed scans)\n";
  }
  return text;
}

std::string FormatRelationsJson(const RelationsReport& r) {
  const RelationsResult& x = r.result;
  std::ostringstream out;
  out << "{\"mode\": \"relations\", \"relations_file\": " << JsonString(r.relations_path)
      << ", \"map\": " << JsonString(r.map_path)
      << ", \"robot\": " << (r.robot.empty() ? "null" : JsonString(r.robot))
      << ", \"map_update\": " << r.map_update << ", \"estimate_poses\": " << r.estimate_poses
      << ", \"max_time_gap_s\": " << Number(r.max_time_gap_s)
      << ", \"odometry\": " << (r.odometry_path.empty() ? "null" : JsonString(r.odometry_path))
      << ", \"completed_trajectories\": " << r.completed_trajectories
      << ", \"time_repaired_ends\": " << r.time_repaired_ends << ", \"relations\": " << x.relations
      << ", \"evaluated\": " << x.evaluated
      << ", \"skipped\": {\"outside_span\": " << x.skipped_outside_span
      << ", \"no_pose_near\": " << x.skipped_no_pose_near
      << ", \"across_frames\": " << x.skipped_across_frames
      << "}, \"translation_m\": " << StatsJson(x.translation_m)
      << ", \"rotation_rad\": " << StatsJson(x.rotation_rad)
      << ", \"translation_sq_mean_m2\": " << Number(x.translation_sq_mean_m2)
      << ", \"rotation_sq_mean_rad2\": " << Number(x.rotation_sq_mean_rad2) << "}\n";
  return out.str();
}

}  // namespace anchormap
