#pragma once
// The viewer's bridge from the bus to its state: decodes the server's outputs with the
// codec (which validates them) and applies them to ViewerState, the merged map each time
// MergedMapAssembler completes one from its header and chunks; refusals are counted like
// the daemons count them. The only part of the viewer that meets the codec.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

#include "common/bus/authenticator.h"
#include "common/bus/channels.h"
#include "common/bus/merged_map_assembler.h"
#include "common/util/reject_counter.h"
#include "tools/viewer/viewer_state.h"

namespace anchormap::viewer {

struct ViewerChannels {
  std::string map_header = channels::kMapHeader;
  std::string map_chunks = channels::kMapChunks;
  std::string merged_map = channels::kMergedMap;  // servers before the chunks
  std::string grid_tiles = channels::kGridTiles;
  std::string anchor_covariances = channels::kAnchorCovariances;
  std::string status = channels::kServerStatus;
};

class ViewerNode {
 public:
  ViewerNode(ViewerChannels channels, ViewerState* state);
  // From now on every message must be sealed by the server under one of `authenticator`'s
  // keys (anchormap-server --key-file signs its outputs): a forged map, a replayed or
  // unsigned one is refused and counted (unsigned, unknown_key, bad_tag, replay) instead of
  // drawn.
  void RequireAuthentication(Authenticator authenticator);
  // Decodes and applies one message; false when refused (counted) or on another channel.
  bool OnMessage(const std::string& channel, const uint8_t* data, size_t size, int64_t wall_utime);
  const ViewerChannels& channels() const { return channels_; }
  const RejectCounter& rejections() const { return rejections_; }
  int64_t messages() const { return messages_; }

 private:
  ViewerChannels channels_;
  ViewerState* state_;
  RejectCounter rejections_;
  MergedMapAssembler assembler_;
  int64_t messages_ = 0;
  std::optional<Authenticator> authenticator_;
};

}  // namespace anchormap::viewer
