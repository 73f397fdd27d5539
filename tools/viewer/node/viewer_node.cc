#include "tools/viewer/node/viewer_node.h"

#include <utility>
#include <vector>

#include "common/bus/map_codec.h"

namespace anchormap::viewer {
namespace {

// A decoded value, or nullptr with the refusal counted.
template <typename T>
const T* Accept(const Result<T>& decoded, const std::string& channel, RejectCounter* rejections) {
  if (decoded.ok()) return &*decoded;
  rejections->Count(decoded.status(), channel);
  return nullptr;
}

}  // namespace

ViewerNode::ViewerNode(ViewerChannels channels, ViewerState* state)
    : channels_(std::move(channels)),
      state_(state),
      assembler_({channels_.map_header, channels_.map_chunks, channels_.merged_map}) {}

void ViewerNode::RequireAuthentication(Authenticator authenticator) {
  authenticator_.emplace(std::move(authenticator));
}

bool ViewerNode::OnMessage(const std::string& channel, const uint8_t* data, size_t size,
                           int64_t wall_utime) {
  const bool known = assembler_.IsMapChannel(channel) || channel == channels_.grid_tiles ||
                     channel == channels_.anchor_covariances || channel == channels_.status;
  if (!known) return false;
  ++messages_;
  std::vector<uint8_t> opened;
  if (authenticator_) {
    Result<std::vector<uint8_t>> payload = authenticator_->Open(channel, data, size);
    if (!payload.ok()) {
      rejections_.Count(payload.status(), channel);
      return false;
    }
    opened = std::move(*payload);
    data = opened.data();
    size = opened.size();
  }
  if (assembler_.IsMapChannel(channel)) {
    bool completed = false;
    if (Status status = assembler_.Accept(channel, data, size, &completed); !status.ok()) {
      rejections_.Count(status, channel);
      return false;
    }
    return !completed || state_->ApplyMergedMap(*assembler_.map(), wall_utime);
  }
  if (channel == channels_.grid_tiles) {
    const auto decoded = DecodeGridTile(data, size);
    const GridTile* tile = Accept(decoded, channel, &rejections_);
    return tile && state_->ApplyGridTile(*tile, wall_utime);
  }
  if (channel == channels_.anchor_covariances) {
    const auto decoded = DecodeAnchorCovariances(data, size);
    const AnchorCovariances* anchors = Accept(decoded, channel, &rejections_);
    return anchors && state_->ApplyAnchorCovariances(*anchors, wall_utime);
  }
  if (channel == channels_.status) {
    const auto decoded = DecodeServerStatus(data, size);
    const ServerStatus* status = Accept(decoded, channel, &rejections_);
    return status && state_->ApplyStatus(*status, wall_utime);
  }
  return false;  // (not reached: `known` above)
}

}  // namespace anchormap::viewer
