#include "common/bus/delivery_codec.h"

#include "anchormap/delivery_ack_t.hpp"
#include "anchormap/resend_request_t.hpp"
#include "common/bus/codec_internal.h"
#include "common/bus/wire_check.h"

namespace anchormap {
namespace {

using codec_internal::CheckName;
using codec_internal::Encode;
using codec_internal::SafeDecode;
using codec_internal::Success;

}  // namespace

Status CheckDeliveryAckWire(const void* data, size_t size) {
  WireCursor c(data, size);
  if (Status p = CheckFingerprint<anchormap::delivery_ack_t>(&c); !p.ok()) return p;
  if (Status p = c.SkipField(8, "utime"); !p.ok()) return p;
  if (Status p = c.SkipString("robot", CodecLimits::kMaxNameLength); !p.ok()) return p;
  return c.SkipField(8 + 4 + 4, "ack fields");
}

Status CheckResendRequestWire(const void* data, size_t size) {
  WireCursor c(data, size);
  if (Status p = CheckFingerprint<anchormap::resend_request_t>(&c); !p.ok()) return p;
  if (!c.Skip(8)) return TruncatedAt("utime");
  if (Status p = c.SkipString("robot", CodecLimits::kMaxNameLength); !p.ok()) return p;
  if (!c.Skip(8)) return TruncatedAt("trajectory_id");
  int32_t n = 0;
  if (Status p = c.ReadCount("num_ranges", kMaxResendRanges, 1 + 4 + 4, &n); !p.ok()) return p;
  if (!c.Skip(9 * static_cast<size_t>(n))) return TruncatedAt("ranges");
  return Status::Ok();
}

Result<DeliveryAck> DecodeDeliveryAck(const void* data, size_t size) {
  anchormap::delivery_ack_t m;
  if (Status p = SafeDecode(data, size, CheckDeliveryAckWire, &m); !p.ok()) return p;
  if (Status p = CheckName(m.robot, "robot"); !p.ok()) return p;
  if (m.keyframes_next < 0 || m.encounters_next < 0) {
    return Status::Error(ErrorCode::kBadSequence, "negative acknowledged sequence number");
  }
  DeliveryAck ack;
  ack.utime = m.utime;
  ack.robot = m.robot;
  ack.trajectory_id = m.trajectory_id;
  ack.keyframes_next = m.keyframes_next;
  ack.encounters_next = m.encounters_next;
  return Success(std::move(ack));
}

std::vector<uint8_t> EncodeDeliveryAck(const DeliveryAck& ack) {
  anchormap::delivery_ack_t m;
  m.utime = ack.utime;
  m.robot = ack.robot;
  m.trajectory_id = ack.trajectory_id;
  m.keyframes_next = ack.keyframes_next;
  m.encounters_next = ack.encounters_next;
  return Encode(m);
}

Result<ResendRequest> DecodeResendRequest(const void* data, size_t size) {
  anchormap::resend_request_t m;
  if (Status p = SafeDecode(data, size, CheckResendRequestWire, &m); !p.ok()) return p;
  if (Status p = CheckName(m.robot, "robot"); !p.ok()) return p;
  ResendRequest request;
  request.utime = m.utime;
  request.robot = m.robot;
  request.trajectory_id = m.trajectory_id;
  for (int32_t i = 0; i < m.num_ranges; ++i) {
    if (m.kind[i] != 0 && m.kind[i] != 1) {
      return Status::Error(ErrorCode::kInvalidValue, "resend range kind not 0 or 1");
    }
    if (m.first[i] < 0 || m.last[i] < m.first[i]) {
      return Status::Error(ErrorCode::kBadSequence,
                           "resend range first..last not 0 <= first <= last");
    }
    request.ranges.push_back(
        {m.kind[i] == 0 ? StreamKind::kKeyframes : StreamKind::kEncounters, m.first[i], m.last[i]});
  }
  return Success(std::move(request));
}

std::vector<uint8_t> EncodeResendRequest(const ResendRequest& request) {
  anchormap::resend_request_t m;
  m.utime = request.utime;
  m.robot = request.robot;
  m.trajectory_id = request.trajectory_id;
  m.num_ranges = static_cast<int32_t>(request.ranges.size());
  for (const SeqRange& r : request.ranges) {
    m.kind.push_back(static_cast<int8_t>(r.kind));
    m.first.push_back(r.first);
    m.last.push_back(r.last);
  }
  return Encode(m);
}

}  // namespace anchormap
