#include "tools/import_carmen/carmen_log.h"

#include <zlib.h>

#include <cerrno>
#include <cmath>
#include <cstring>

#include "common/util/text_fields.h"

namespace anchormap {
namespace {

constexpr int64_t kMaxReadings = 100000;             // more than any planar laser has
constexpr size_t kMaxLineBytes = 64u * 1024 * 1024;  // a sane bound against binary junk

using Fields = std::vector<std::string_view>;

Status FieldError(std::string_view type, const std::string& what, std::string_view field,
                  const char* expected) {
  return Status::Error(std::string(type) + ": " + what + " '" + Abbreviate(field) + "' is not " +
                       expected);
}

Status CountError(std::string_view type, size_t expected, const std::string& detail, size_t found,
                  bool at_least = false) {
  return Status::Error(std::string(type) + ": expected " + (at_least ? "at least " : "") +
                       std::to_string(expected) + " fields after the message name" + detail +
                       ", found " + std::to_string(found));
}

// Reads fields[index] as a finite double into *value.
Status ReadDouble(std::string_view type, const Fields& fields, size_t index, const char* name,
                  double* value) {
  if (!ParseFiniteDouble(fields[index], value)) {
    return FieldError(type, name, fields[index], "a finite number");
  }
  return Status::Ok();
}

Status ReadCount(std::string_view type, const Fields& fields, size_t index, const char* name,
                 int64_t min_value, int64_t* value) {
  if (!ParseInt64(fields[index], value)) return FieldError(type, name, fields[index], "an integer");
  if (*value < min_value || *value > kMaxReadings) {
    return Status::Error(std::string(type) + ": " + name + " " + std::to_string(*value) +
                         " is out of range [" + std::to_string(min_value) + ", " +
                         std::to_string(kMaxReadings) + "]");
  }
  return Status::Ok();
}

// Reads `count` non-negative finite values starting at fields[first].
Status ReadValues(std::string_view type, const Fields& fields, size_t first, int64_t count,
                  const char* name, std::vector<float>* values) {
  values->resize(static_cast<size_t>(count));
  for (int64_t i = 0; i < count; ++i) {
    double v = 0.0;
    const std::string what =
        std::string(name) + " " + std::to_string(i + 1) + " of " + std::to_string(count);
    if (!ParseFiniteDouble(fields[first + i], &v)) {
      return FieldError(type, what, fields[first + i], "a finite number");
    }
    if (v < 0.0) {
      return Status::Error(std::string(type) + ": " + what + " is negative (" +
                           std::string(fields[first + i]) + ")");
    }
    (*values)[i] = static_cast<float>(v);
  }
  return Status::Ok();
}

// Reads "x y theta" at fields[first..first+2] with the given names.
Status ReadPose(std::string_view type, const Fields& fields, size_t first,
                const char* const names[3], Pose2* pose) {
  double v[3];
  for (int i = 0; i < 3; ++i) {
    if (Status s = ReadDouble(type, fields, first + i, names[i], &v[i]); !s.ok()) return s;
  }
  *pose = Pose2(v[0], v[1], v[2]);
  return Status::Ok();
}

// Reads "ipc_timestamp host logger_timestamp" at fields[first..first+2].
Status ReadTimes(std::string_view type, const Fields& fields, size_t first, double* ipc_time_s,
                 double* logger_time_s) {
  if (Status s = ReadDouble(type, fields, first, "ipc_timestamp", ipc_time_s); !s.ok()) return s;
  return ReadDouble(type, fields, first + 2, "logger_timestamp", logger_time_s);
}

Status ParseOdometry(std::string_view type, const Fields& f, CarmenOdometry* odometry) {
  if (f.size() != 9) {
    return CountError(type, 9, " (x y theta tv rv accel ipc_timestamp host logger_timestamp)",
                      f.size());
  }
  static const char* const kPose[3] = {"x", "y", "theta"};
  if (Status s = ReadPose(type, f, 0, kPose, &odometry->pose); !s.ok()) return s;
  if (Status s = ReadDouble(type, f, 3, "tv", &odometry->tv_mps); !s.ok()) return s;
  if (Status s = ReadDouble(type, f, 4, "rv", &odometry->rv_radps); !s.ok()) return s;
  if (Status s = ReadDouble(type, f, 5, "accel", &odometry->accel_mps2); !s.ok()) return s;
  return ReadTimes(type, f, 6, &odometry->ipc_time_s, &odometry->logger_time_s);
}

static const char* const kLaserPose[3] = {"x", "y", "theta"};
static const char* const kRobotPose[3] = {"odom_x", "odom_y", "odom_theta"};

Status ParseFlaser(std::string_view type, const Fields& f, CarmenLaser* laser) {
  if (f.empty()) return Status::Error(std::string(type) + ": missing num_readings");
  int64_t n = 0;
  if (Status s = ReadCount(type, f, 0, "num_readings", 1, &n); !s.ok()) return s;
  const size_t expected = 1 + static_cast<size_t>(n) + 9;
  if (f.size() != expected) {
    return CountError(type, expected, " for " + std::to_string(n) + " readings", f.size());
  }
  laser->format = CarmenLaserFormat::kFlaser;
  if (Status s = ReadValues(type, f, 1, n, "range", &laser->ranges_m); !s.ok()) return s;
  const size_t pose_at = 1 + static_cast<size_t>(n);
  if (Status s = ReadPose(type, f, pose_at, kLaserPose, &laser->laser_pose); !s.ok()) return s;
  if (Status s = ReadPose(type, f, pose_at + 3, kRobotPose, &laser->robot_pose); !s.ok()) return s;
  laser->remissions.clear();
  laser->start_angle_rad = -0.5 * kPi;
  laser->angular_resolution_rad = CarmenFlaserAngularResolution(static_cast<int>(n));
  laser->fov_rad = CarmenFlaserFov(static_cast<int>(n));
  laser->max_range_m = 0.0;
  laser->tv_mps = laser->rv_radps = 0.0;
  return ReadTimes(type, f, pose_at + 6, &laser->ipc_time_s, &laser->logger_time_s);
}

Status ParseRobotLaser(std::string_view type, const Fields& f, CarmenLaser* laser) {
  // The smallest valid line has one reading and no remissions: 8 + 1 + 1 + 14 fields.
  if (f.size() < 8) return CountError(type, 24, "", f.size(), true);
  int64_t laser_type = 0, remission_mode = 0, n = 0, m = 0;
  double accuracy = 0.0;
  if (!ParseInt64(f[0], &laser_type)) return FieldError(type, "laser_type", f[0], "an integer");
  if (Status s = ReadDouble(type, f, 1, "start_angle", &laser->start_angle_rad); !s.ok()) return s;
  if (Status s = ReadDouble(type, f, 2, "fov", &laser->fov_rad); !s.ok()) return s;
  if (Status s = ReadDouble(type, f, 3, "angular_resolution", &laser->angular_resolution_rad);
      !s.ok()) {
    return s;
  }
  if (Status s = ReadDouble(type, f, 4, "max_range", &laser->max_range_m); !s.ok()) return s;
  if (Status s = ReadDouble(type, f, 5, "accuracy", &accuracy); !s.ok()) return s;
  if (!ParseInt64(f[6], &remission_mode)) {
    return FieldError(type, "remission_mode", f[6], "an integer");
  }
  if (Status s = ReadCount(type, f, 7, "num_readings", 1, &n); !s.ok()) return s;
  const size_t remissions_at = 8 + static_cast<size_t>(n);
  if (f.size() < remissions_at + 1) {
    return CountError(type, remissions_at + 15, " for " + std::to_string(n) + " readings", f.size(),
                      true);
  }
  if (Status s = ReadCount(type, f, remissions_at, "num_remissions", 0, &m); !s.ok()) return s;
  const size_t pose_at = remissions_at + 1 + static_cast<size_t>(m);
  const size_t expected = pose_at + 14;
  if (f.size() != expected) {
    return CountError(
        type, expected,
        " for " + std::to_string(n) + " readings and " + std::to_string(m) + " remissions",
        f.size());
  }
  if (laser->angular_resolution_rad == 0.0 && n > 1) {
    return Status::Error(std::string(type) + ": angular_resolution is 0");
  }
  laser->format = CarmenLaserFormat::kRobotLaser1;
  if (Status s = ReadValues(type, f, 8, n, "range", &laser->ranges_m); !s.ok()) return s;
  if (Status s = ReadValues(type, f, remissions_at + 1, m, "remission", &laser->remissions);
      !s.ok()) {
    return s;
  }
  if (Status s = ReadPose(type, f, pose_at, kLaserPose, &laser->laser_pose); !s.ok()) return s;
  if (Status s = ReadPose(type, f, pose_at + 3, kRobotPose, &laser->robot_pose); !s.ok()) return s;
  if (Status s = ReadDouble(type, f, pose_at + 6, "tv", &laser->tv_mps); !s.ok()) return s;
  if (Status s = ReadDouble(type, f, pose_at + 7, "rv", &laser->rv_radps); !s.ok()) return s;
  static const char* const kSafety[3] = {"forward_safety_dist", "side_safety_dist", "turn_axis"};
  for (int i = 0; i < 3; ++i) {
    double unused = 0.0;
    if (Status s = ReadDouble(type, f, pose_at + 8 + i, kSafety[i], &unused); !s.ok()) return s;
  }
  return ReadTimes(type, f, pose_at + 11, &laser->ipc_time_s, &laser->logger_time_s);
}

bool IsMessageName(std::string_view word) {
  if (word.empty() || word.front() < 'A' || word.front() > 'Z') return false;
  for (char c : word) {
    const bool ok = (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '-';
    if (!ok) return false;
  }
  return true;
}

}  // namespace

double CarmenFlaserFov(int num_readings) {
  switch (num_readings) {
    case 180:
      return kPi / 180.0 * 179.0;  // the 181st beam was dropped
    case 360:
      return kPi / 180.0 * 179.5;
    case 400:
      return kPi / 180.0 * 99.75;
    case 401:
      return kPi / 180.0 * 100.0;
    default:
      return kPi;
  }
}

double CarmenFlaserAngularResolution(int num_readings) {
  switch (num_readings) {
    case 180:
    case 181:
      return kPi / 180.0;
    case 360:
    case 361:
      return kPi / 360.0;
    case 400:
    case 401:
      return kPi / 720.0;
    default:
      return num_readings > 1 ? kPi / (num_readings - 1) : 0.0;
  }
}

Status ParseCarmenLine(std::string_view line, CarmenRecord* record) {
  const Fields all = SplitFields(line);
  record->kind = CarmenRecord::Kind::kIgnored;
  if (all.empty()) {
    record->type.clear();
    return Status::Ok();
  }
  if (all.front().front() == '#') {
    record->type = "#";
    return Status::Ok();
  }
  if (!IsMessageName(all.front())) {
    record->type.clear();
    return Status::Error("line does not start with a message name ('" + Abbreviate(all.front()) +
                         "')");
  }
  record->type.assign(all.front());
  const Fields fields(all.begin() + 1, all.end());
  if (record->type == "ODOM") {
    if (Status s = ParseOdometry(record->type, fields, &record->odometry); !s.ok()) return s;
    record->kind = CarmenRecord::Kind::kOdometry;
  } else if (record->type == "FLASER") {
    if (Status s = ParseFlaser(record->type, fields, &record->laser); !s.ok()) return s;
    record->kind = CarmenRecord::Kind::kLaser;
  } else if (record->type == "ROBOTLASER1") {
    if (Status s = ParseRobotLaser(record->type, fields, &record->laser); !s.ok()) return s;
    record->kind = CarmenRecord::Kind::kLaser;
  }
  return Status::Ok();
}

struct CarmenLogReader::File {
  gzFile gz = nullptr;
  std::string buffer;  // decompressed bytes not yet returned, from `position` on
  size_t position = 0;
  bool at_end = false;
};

CarmenLogReader::CarmenLogReader() : file_(std::make_unique<File>()) {}

CarmenLogReader::~CarmenLogReader() {
  if (file_->gz) gzclose(file_->gz);
}

Status CarmenLogReader::Open(const std::string& path) {
  if (file_->gz) gzclose(file_->gz);
  *file_ = File();
  path_ = path;
  line_number_ = 0;
  errno = 0;
  file_->gz = gzopen(path.c_str(), "rb");
  if (!file_->gz) {
    status_ = Status::Error("cannot open CARMEN log '" + path +
                            "': " + (errno ? std::strerror(errno) : "out of memory"));
    return status_;
  }
  status_ = Status::Ok();
  return status_;
}

// Reads with gzread into a buffer and splits at '\n' itself: gzgets would cut a line at an
// embedded NUL byte and merge the rest with the next line, shifting every later line number.
bool CarmenLogReader::ReadLine(std::string* line) {
  line->clear();
  if (!file_->gz || !status_.ok()) return false;
  const auto fail = [&](const std::string& reason) {
    status_ = Status::Error(path_ + ":" + std::to_string(line_number_ + 1) + ": " + reason);
    return false;
  };
  for (;;) {
    const size_t newline = file_->buffer.find('\n', file_->position);
    if (newline != std::string::npos) {
      line->assign(file_->buffer, file_->position, newline - file_->position);
      file_->position = newline + 1;
      break;
    }
    if (file_->at_end) {
      if (file_->position >= file_->buffer.size()) return false;
      line->assign(file_->buffer, file_->position, std::string::npos);  // no final newline
      file_->position = file_->buffer.size();
      break;
    }
    if (file_->buffer.size() - file_->position > kMaxLineBytes) {
      return fail("line longer than 64 MiB");
    }
    file_->buffer.erase(0, file_->position);
    file_->position = 0;
    char chunk[256 * 1024];
    const int read = gzread(file_->gz, chunk, sizeof(chunk));
    if (read < 0) {
      int error = Z_OK;
      const char* message = gzerror(file_->gz, &error);
      return fail(std::string("read error: ") +
                  (error == Z_ERRNO ? std::strerror(errno) : message));
    }
    if (read == 0) {
      int error = Z_OK;
      const char* message = gzerror(file_->gz, &error);
      if (error != Z_OK && error != Z_STREAM_END) {
        return fail(std::string("read error: ") +
                    (error == Z_ERRNO ? std::strerror(errno) : message));
      }
      file_->at_end = true;
    }
    file_->buffer.append(chunk, static_cast<size_t>(read));
  }
  if (!line->empty() && line->back() == '\r') line->pop_back();
  ++line_number_;
  return true;
}

}  // namespace anchormap
