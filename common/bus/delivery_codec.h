#pragma once
// Wire bytes <-> validated delivery values (common/types/delivery.h):
// anchormap.delivery_ack_t and anchormap.resend_request_t. Like codec.h: decoding never
// throws, sizes are checked before anything is allocated, every failure is a Status.

#include <cstddef>
#include <cstdint>
#include <vector>

#include "common/types/delivery.h"
#include "common/util/status.h"

namespace anchormap {

// At most this many ranges in one resend request.
inline constexpr int32_t kMaxResendRanges = 1000;

Result<DeliveryAck> DecodeDeliveryAck(const void* data, size_t size);
std::vector<uint8_t> EncodeDeliveryAck(const DeliveryAck& ack);

Result<ResendRequest> DecodeResendRequest(const void* data, size_t size);
std::vector<uint8_t> EncodeResendRequest(const ResendRequest& request);

// Pre-flight size checks (see wire_check.h).
Status CheckDeliveryAckWire(const void* data, size_t size);
Status CheckResendRequestWire(const void* data, size_t size);

}  // namespace anchormap
