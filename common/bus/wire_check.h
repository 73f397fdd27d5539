#pragma once
// Pre-flight checks of LCM wire bytes before lcm-gen's decode() sees them.
//
// lcm-gen's C++ decoders resize a vector to whatever length field the bytes carry before
// checking that the buffer holds that many elements: a 20-byte datagram claiming 2^31
// ranges makes them allocate (and zero) 8 GB. These walkers read only the length fields
// and string headers of each type, check the 8-byte fingerprint, and refuse any length
// that exceeds the remaining bytes or the sanity limits, so decode() runs only on buffers
// whose sizes are consistent.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

#include "common/util/reject_counter.h"

namespace anchormap {

struct WireProblem {
  ErrorCode reason = ErrorCode::kDecodeFailed;
  std::string detail;
};

// Reads big-endian LCM primitives from a byte buffer without ever reading past its end.
class WireCursor {
 public:
  WireCursor(const void* data, size_t size)
      : bytes_(static_cast<const uint8_t*>(data)), size_(data ? size : 0) {}

  size_t remaining() const { return size_ - position_; }
  bool Skip(size_t n);
  bool ReadInt32(int32_t* value);
  bool ReadUint64(uint64_t* value);
  // An LCM string: int32 length including the terminating NUL, then the bytes.
  std::optional<WireProblem> SkipString(const char* field, size_t max_length);
  // An int32 element count, checked against [0, max_count] and against the bytes left
  // for `count * min_element_bytes`.
  std::optional<WireProblem> ReadCount(const char* field, int32_t max_count,
                                       size_t min_element_bytes, int32_t* count);

 private:
  const uint8_t* bytes_;
  size_t size_;
  size_t position_ = 0;
};

// One walker per wire type; each returns nullopt when the sizes are consistent.
std::optional<WireProblem> CheckPlanarLidarWire(const void* data, size_t size);
std::optional<WireProblem> CheckPoseWire(const void* data, size_t size);
std::optional<WireProblem> CheckKeyframeWire(const void* data, size_t size);
std::optional<WireProblem> CheckEncounterWire(const void* data, size_t size);
std::optional<WireProblem> CheckMergedMapWire(const void* data, size_t size);
std::optional<WireProblem> CheckAnchorCovariancesWire(const void* data, size_t size);
std::optional<WireProblem> CheckGridTileWire(const void* data, size_t size);
std::optional<WireProblem> CheckServerStatusWire(const void* data, size_t size);

}  // namespace anchormap
