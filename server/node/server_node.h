#pragma once
// The mapping server between bytes and logic: decodes keyframes and encounters with the
// codec (refusals counted in the server's RejectCounter, per channel), feeds MappingServer,
// and encodes its outputs for a publish callback. The online main connects it to an
// LcmLoop (callback = LCM publish, clock = wall time); the offline main to an LCM log file
// (callback = log writer, clock = data time). No LCM header here: bytes only.

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "server/mapping_server.h"
#include "server/node/server_options.h"

namespace anchormap {

class ServerNode {
 public:
  using Publish =
      std::function<void(const std::string& channel, const std::vector<uint8_t>& bytes)>;

  ServerNode(const ServerOptions& options, Publish publish);

  // One message; channels other than the keyframe and encounter channels are ignored.
  // Returns true when the channel was one of them.
  bool OnMessage(const std::string& channel, const uint8_t* data, size_t size);
  // Publishes what is due at `now_utime` (the caller's clock): the merged map and anchor
  // covariances after an update (at most once per map period), the grid tiles at most once
  // per grid period.
  void PublishDue(int64_t now_utime);
  void PublishStatus();
  // Publishes map, covariances, grid tiles and status now (end of an offline run).
  void PublishAll();
  // Online delivery: acknowledgements of every trajectory; resend requests that are due.
  void PublishAcks();
  void PublishResendRequests();

  MappingServer& server() { return server_; }
  int64_t published_maps() const { return published_maps_; }
  int64_t published_grids() const { return published_grids_; }

 private:
  void PublishMap();
  void PublishGrid();

  ServerOptions options_;
  Publish publish_;
  MappingServer server_;
  int64_t published_maps_ = 0;
  int64_t published_grids_ = 0;
};

}  // namespace anchormap
