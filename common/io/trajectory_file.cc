#include "common/io/trajectory_file.h"

#include <cmath>
#include <cstdio>
#include <fstream>

#include "common/util/text_fields.h"

namespace anchormap {
namespace {

const std::vector<const char*> kFieldNames = {"timestamp", "x", "y", "z", "qx", "qy", "qz", "qw"};

bool IsCommentOrBlank(std::string_view line) {
  const auto fields = SplitFields(line, true);
  return fields.empty() || fields.front().front() == '#';
}

}  // namespace

Status ParseTrajectoryLine(std::string_view line, StampedPose2* pose) {
  std::vector<double> v;
  if (Status parsed = ParseNumberFields(line, kFieldNames, /*commas_separate=*/true, &v);
      !parsed.ok()) {
    return parsed;
  }
  const double qx = v[4], qy = v[5], qz = v[6], qw = v[7];
  const double norm = std::sqrt(qx * qx + qy * qy + qz * qz + qw * qw);
  if (std::abs(norm - 1.0) > 1e-3) {
    return Status::Error("quaternion norm " + std::to_string(norm) + " is not 1");
  }
  // Yaw of the ZYX Euler decomposition; exact for a yaw-only quaternion.
  const double yaw = YawOfQuaternion(qw, qx, qy, qz);
  pose->utime = std::llround(v[0] * 1e6);
  pose->pose = Pose2(v[1], v[2], yaw);
  return Status::Ok();
}

std::string FormatTrajectoryLine(const StampedPose2& pose) {
  const double half = 0.5 * pose.pose.theta();
  // utime / 1e6 printed via integer parts so that large Unix times keep all 6 decimals.
  const int64_t seconds = pose.utime >= 0 ? pose.utime / 1000000 : -((-pose.utime) / 1000000);
  const int64_t micros = std::abs(pose.utime - seconds * 1000000);
  char buffer[256];
  std::snprintf(buffer, sizeof(buffer), "%s%lld.%06lld %.10g %.10g 0 0 0 %.10g %.10g",
                (pose.utime < 0 && seconds == 0) ? "-" : "", static_cast<long long>(seconds),
                static_cast<long long>(micros), pose.pose.x(), pose.pose.y(), std::sin(half),
                std::cos(half));
  return buffer;
}

Status ReadTrajectoryFile(const std::string& path, StampedTrajectory* poses) {
  std::ifstream in(path);
  if (!in) return Status::Error("cannot open trajectory file '" + path + "'");
  poses->clear();
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (IsCommentOrBlank(line)) continue;
    StampedPose2 pose;
    const Status status = ParseTrajectoryLine(line, &pose);
    if (!status.ok()) {
      return Status::Error(path + ":" + std::to_string(line_number) + ": " + status.message());
    }
    poses->push_back(pose);
  }
  if (in.bad()) return Status::Error(path + ": read error");
  return Status::Ok();
}

Status WriteTrajectoryFile(const std::string& path, const StampedTrajectory& poses,
                           const std::string& comment) {
  std::ofstream out(path);
  if (!out) return Status::Error("cannot open trajectory file '" + path + "' for writing");
  out << "# timestamp x y z qx qy qz qw\n";
  if (!comment.empty()) out << "# " << comment << "\n";
  for (const StampedPose2& pose : poses) out << FormatTrajectoryLine(pose) << "\n";
  out.flush();
  if (!out) return Status::Error("write to trajectory file '" + path + "' failed");
  return Status::Ok();
}

}  // namespace anchormap
