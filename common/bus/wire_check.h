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
#include <string>

#include "common/util/status.h"

namespace anchormap {

// Reads big-endian LCM primitives from a byte buffer without ever reading past its end.
class WireCursor {
 public:
  WireCursor(const void* data, size_t size)
      : bytes_(static_cast<const uint8_t*>(data)), size_(data ? size : 0) {}

  size_t remaining() const { return size_ - position_; }
  bool Skip(size_t n);
  // Skip(n), or the "truncated message at `field`" refusal.
  Status SkipField(size_t n, const char* field);
  bool ReadInt32(int32_t* value);
  bool ReadUint64(uint64_t* value);
  // An LCM string: int32 length including the terminating NUL, then the bytes.
  Status SkipString(const char* field, size_t max_length);
  // An int32 element count, checked against [0, max_count] and against the bytes left
  // for `count * min_element_bytes`.
  Status ReadCount(const char* field, int32_t max_count, size_t min_element_bytes, int32_t* count);

 private:
  const uint8_t* bytes_;
  size_t size_;
  size_t position_ = 0;
};

// The refusal of a message that ends inside `field`.
Status TruncatedAt(const char* field);

// The 8-byte fingerprint every LCM message starts with must be T's (an lcm-gen type).
template <typename T>
Status CheckFingerprint(WireCursor* cursor) {
  uint64_t hash = 0;
  if (!cursor->ReadUint64(&hash)) return TruncatedAt("fingerprint");
  if (hash != static_cast<uint64_t>(T::getHash())) {
    return Status::Error(ErrorCode::kDecodeFailed,
                         std::string("fingerprint is not ") + T::getTypeName());
  }
  return Status::Ok();
}

// One walker per wire type; each is ok when the sizes are consistent.
Status CheckPlanarLidarWire(const void* data, size_t size);
Status CheckPoseWire(const void* data, size_t size);
Status CheckKeyframeWire(const void* data, size_t size);
// anchormap.keyframe_v1_t: keyframe_t before it carried encounters_relayed (old journals).
Status CheckKeyframeV1Wire(const void* data, size_t size);
Status CheckEncounterWire(const void* data, size_t size);
Status CheckMergedMapWire(const void* data, size_t size);
Status CheckMergedMapHeaderWire(const void* data, size_t size);
Status CheckMergedMapChunkWire(const void* data, size_t size);
Status CheckAnchorCovariancesWire(const void* data, size_t size);
Status CheckGridTileWire(const void* data, size_t size);
Status CheckServerStatusWire(const void* data, size_t size);

}  // namespace anchormap
