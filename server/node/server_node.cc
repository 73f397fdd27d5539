#include "server/node/server_node.h"

#include "common/bus/codec.h"
#include "common/bus/delivery_codec.h"
#include "common/bus/map_codec.h"

namespace anchormap {

ServerNode::ServerNode(const ServerOptions& options, Publish publish)
    : options_(options), publish_(std::move(publish)), server_(options.server) {}

bool ServerNode::OnMessage(const std::string& channel, const uint8_t* data, size_t size) {
  // The logic counts its own refusals; the node counts what does not decode.
  if (channel == options_.channels.keyframes) {
    Result<Keyframe> keyframe = DecodeKeyframe(data, size);
    if (!keyframe.ok()) server_.CountRejection(keyframe.status(), channel);
    if (keyframe.ok()) (void)server_.OnKeyframe(std::move(*keyframe));
    return true;
  }
  if (channel == options_.channels.encounters) {
    const Result<Encounter> encounter = DecodeEncounter(data, size);
    if (!encounter.ok()) server_.CountRejection(encounter.status(), channel);
    if (encounter.ok()) (void)server_.OnEncounter(*encounter);
    return true;
  }
  return false;
}

void ServerNode::PublishMap() {
  publish_(options_.channels.merged_map, EncodeMergedMap(server_.BuildMergedMap()));
  publish_(options_.channels.anchor_covariances,
           EncodeAnchorCovariances(server_.BuildAnchorCovariances()));
  ++published_maps_;
}

void ServerNode::PublishGrid() {
  for (const GridTile& tile : server_.BuildGridTiles()) {
    publish_(options_.channels.grid_tiles, EncodeGridTile(tile));
  }
  ++published_grids_;
}

void ServerNode::PublishDue(int64_t now_utime) {
  MapPublisher& publisher = server_.publisher();
  const int64_t update = server_.update_count();
  if (publisher.MapDue(now_utime, update)) {
    PublishMap();
    publisher.MarkMapPublished(now_utime, update);
  }
  if (publisher.GridDue(now_utime, update)) {
    PublishGrid();
    publisher.MarkGridPublished(now_utime, update);
  }
}

void ServerNode::PublishStatus() {
  publish_(options_.channels.status, EncodeServerStatus(server_.BuildStatus()));
}

void ServerNode::PublishAcks() {
  for (const DeliveryAck& ack : server_.BuildAcks()) {
    publish_(options_.channels.acks, EncodeDeliveryAck(ack));
  }
}

void ServerNode::PublishResendRequests() {
  for (const ResendRequest& request : server_.BuildResendRequests()) {
    publish_(options_.channels.resend_requests, EncodeResendRequest(request));
  }
}

void ServerNode::PublishAll() {
  PublishMap();
  PublishGrid();
  PublishStatus();
}

}  // namespace anchormap
