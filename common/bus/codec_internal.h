#pragma once
// Helpers shared by codec.cc and map_codec.cc (not part of the public codec API).

#include <cmath>
#include <exception>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "common/bus/codec.h"
#include "common/bus/wire_check.h"

namespace anchormap::codec_internal {

template <typename T>
std::vector<uint8_t> Encode(const T& message) {
  std::vector<uint8_t> bytes(static_cast<size_t>(message.getEncodedSize()));
  message.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  return bytes;
}

// Runs the pre-flight size check, then lcm-gen's decode; exceptions (a string length
// the check did not foresee) become decode failures.
template <typename T, typename Check>
Status SafeDecode(const void* data, size_t size, Check check, T* message) {
  if (Status problem = check(data, size); !problem.ok()) return problem;
  try {
    const int used = message->decode(data, 0, static_cast<int>(size));
    if (used < 0 || static_cast<size_t>(used) != size) {
      return Status::Error(ErrorCode::kDecodeFailed,
                           "does not decode as " + std::string(T::getTypeName()));
    }
  } catch (const std::exception& error) {
    return Status::Error(ErrorCode::kDecodeFailed, error.what());
  }
  return Status::Ok();
}

inline bool AllFinite(const double* values, int n) {
  for (int i = 0; i < n; ++i) {
    if (!std::isfinite(values[i])) return false;
  }
  return true;
}

inline Eigen::Matrix3d MatrixFromRowMajor(const double values[9]) {
  Eigen::Matrix3d m;
  m << values[0], values[1], values[2], values[3], values[4], values[5], values[6], values[7],
      values[8];
  return m;
}

inline void MatrixToRowMajor(const Eigen::Matrix3d& m, double values[9]) {
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) values[3 * r + c] = m(r, c);
  }
}

inline void PoseToArray(const Pose2& pose, double values[3]) {
  values[0] = pose.x();
  values[1] = pose.y();
  values[2] = pose.theta();
}

inline Pose2 PoseFromArray(const double values[3]) {
  return Pose2(values[0], values[1], values[2]);
}

// Empty, overlong or non-printable names are refused.
inline Status CheckName(const std::string& name, const char* field) {
  if (name.empty())
    return Status::Error(ErrorCode::kEmptyRobotName, std::string(field) + " is empty");
  for (char ch : name) {
    if (ch <= ' ' || ch > '~') {
      return Status::Error(ErrorCode::kInvalidValue,
                           std::string(field) + " has a non-printable character");
    }
  }
  return Status::Ok();
}

inline Status CheckScanGeometry(float rad0, float radstep, size_t nranges) {
  if (!std::isfinite(rad0) || !std::isfinite(radstep)) {
    return Status::Error(ErrorCode::kNotFinite, "rad0 or radstep is not finite");
  }
  if (nranges > 1 && radstep == 0.0f) {
    return Status::Error(ErrorCode::kInvalidValue, "radstep is 0");
  }
  if (std::abs(static_cast<double>(radstep)) * (static_cast<double>(nranges) - 1.0) >
      2.0 * kPi + 1e-3) {
    return Status::Error(ErrorCode::kInvalidValue, "scan covers more than 360 degrees");
  }
  return Status::Ok();
}

inline Status CheckRanges(const std::vector<float>& ranges) {
  for (size_t i = 0; i < ranges.size(); ++i) {
    if (!std::isfinite(ranges[i])) {
      return Status::Error(ErrorCode::kNotFinite, "range " + std::to_string(i) + " is not finite");
    }
    if (ranges[i] < 0.0f) {
      return Status::Error(ErrorCode::kInvalidValue, "range " + std::to_string(i) + " is negative");
    }
  }
  return Status::Ok();
}

// A message time: 0 <= utime <= CodecLimits::kMaxUtime.
inline Status CheckUtime(int64_t utime) {
  if (utime < 0) return Status::Error(ErrorCode::kInvalidValue, "negative utime");
  if (utime > CodecLimits::kMaxUtime) {
    return Status::Error(ErrorCode::kInvalidValue,
                         "utime " + std::to_string(utime) + " is beyond any plausible clock");
  }
  return Status::Ok();
}

// A decoded value (named for the reader: every path ends in a Status or a Success).
template <typename T>
Result<T> Success(T value) {
  return Result<T>(std::move(value));
}

}  // namespace anchormap::codec_internal
