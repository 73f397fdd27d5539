// anchormap-viewer: the live map in a browser. Subscribes to the mapping server's outputs
// (merged map, grid tiles, anchor covariances, status) and serves one web page over HTTP
// that follows the map through a WebSocket. Runs anywhere on the robots' network, like
// lcm-spy; the server does not know it is there.

#include <chrono>
#include <iostream>
#include <memory>
#include <sstream>

#include "common/bus/authenticator.h"
#include "common/bus/lcm_loop.h"
#include "common/util/log.h"
#include "common/util/options_loader.h"
#include "tools/viewer/log_follower.h"
#include "tools/viewer/node/viewer_node.h"
#include "tools/viewer/viewer_state.h"
#include "tools/viewer/web_server.h"

namespace anchormap::viewer {
namespace {

struct ViewerOptions {
  std::string lcm_url;
  std::string follow_log;
  ViewerChannels channels;
  WebServerOptions web;
  int push_period_ms = 200;
  double status_period_s = 5.0;
  int queue_capacity = 1000;
  int max_tiles = 20000;
  std::string log_level = "info";
  std::string key_file;
};

int64_t WallUtime() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

void Register(OptionsLoader* l, ViewerOptions* o, int* max_queue_mb) {
  AddLcmUrlOption(l, &o->lcm_url);
  l->Add("follow_log", "follow-log", &o->follow_log,
         "read the server's outputs from this LCM log file as it grows (e.g. lcm-logger's) "
         "instead of the bus");
  l->Add("http.address", "http-address", &o->web.address,
         "address to serve the page on (0.0.0.0: every interface)");
  l->Add("http.port", "http-port", &o->web.port, "TCP port of the page (0: any free port)");
  l->Add("http.max_clients", "max-clients", &o->web.max_clients, "browsers connected at once");
  l->Add("http.max_client_queue_mb", "max-client-queue-mb", max_queue_mb,
         "updates queued for one slow browser before they are dropped for a full resync (MB)");
  l->Add("http.compress", "http-compress", &o->web.compress,
         "compress WebSocket messages (permessage-deflate) for browsers that offer it");
  l->Add("push_period_ms", "push-period-ms", &o->push_period_ms,
         "changes go to the browsers at most this often (ms)");
  l->Add("max_tiles", "max-tiles", &o->max_tiles, "grid tiles held (more are refused)");
  l->Add("status_period_s", "status-period-s", &o->status_period_s,
         "status line period (s; 0 = off)");
  l->Add("queue_capacity", "queue-capacity", &o->queue_capacity,
         "LCM receive queue per subscription, messages");
  l->Add("log_level", "log-level", &o->log_level, "debug, info, warning or error");
  l->Add("key_file", "key-file", &o->key_file,
         "accept only the server's outputs signed with a key of this file (the server's "
         "--key-file; empty: unsigned outputs, with a warning)");
  l->Add("channels.map_header", "map-header-channel", &o->channels.map_header,
         "merged_map_header_t input");
  l->Add("channels.map_chunks", "map-chunks-channel", &o->channels.map_chunks,
         "merged_map_chunk_t input");
  l->Add("channels.merged_map", "merged-map-channel", &o->channels.merged_map,
         "merged_map_t input (servers before the chunks)");
  l->Add("channels.grid_tiles", "grid-tiles-channel", &o->channels.grid_tiles, "grid_tile_t input");
  l->Add("channels.anchor_covariances", "anchor-covariances-channel",
         &o->channels.anchor_covariances, "anchor_covariances_t input");
  l->Add("channels.status", "status-channel", &o->channels.status, "server_status_t input");
}

// With a key file the viewer checks the server's signature on every output (like the
// server checks the agents'); without, it warns: anyone on the network could draw a map.
Status SetUpAuthentication(const std::string& key_file, ViewerNode* node) {
  if (key_file.empty()) {
    LogWarning(
        "no --key-file: the server's outputs are not authenticated; anyone on the "
        "network can publish a map this viewer draws");
    return Status::Ok();
  }
  AuthenticatorOptions auth;
  auth.sender = "viewer";  // (it never signs)
  Result<Authenticator> authenticator = LoadAuthenticator(key_file, auth);
  if (!authenticator.ok()) return authenticator.status();
  LogInfo("authentication on: the server's outputs are checked against the keys of " + key_file);
  node->RequireAuthentication(std::move(*authenticator));
  return Status::Ok();
}

int Run(const ViewerOptions& options) {
  const bool following = !options.follow_log.empty();
  Result<std::unique_ptr<LcmLoop>> created =
      LcmLoop::Create(following ? "memq://" : options.lcm_url);
  if (!created.ok()) {
    LogError(created.status().message());
    return 1;
  }
  std::unique_ptr<LcmLoop> loop = std::move(*created);
  ViewerStateOptions state_options;
  state_options.max_tiles = options.max_tiles;
  ViewerState state(state_options);
  ViewerNode node(options.channels, &state);
  if (Status s = SetUpAuthentication(options.key_file, &node); !s.ok()) {
    LogError(s.message());
    return 1;
  }
  std::unique_ptr<WebServer> web;
  auto push = [&state, &web] {
    if (!state.HasChanges()) return;
    web->Broadcast(std::make_shared<const std::string>(state.TakeDelta().dump()));
  };
  web = std::make_unique<WebServer>(loop->io(), options.web, [&state, &push] {
    push();  // pending changes go to the clients that have the previous state
    return std::make_shared<const std::string>(state.Full().dump());
  });
  if (Status s = web->Start(); !s.ok()) {
    LogError(s.message());
    return 1;
  }
  auto handler = [&node](const std::string& channel, const uint8_t* data, size_t size) {
    node.OnMessage(channel, data, size, WallUtime());
  };
  LogFollower follower(options.follow_log);
  if (following) {
    loop->Every(std::chrono::milliseconds(100), [&] {
      for (const FollowedEvent& e : follower.Poll()) {
        handler(e.channel, e.data.data(), e.data.size());
      }
    });
  } else {
    for (const std::string& channel :
         {options.channels.map_header, options.channels.map_chunks, options.channels.merged_map,
          options.channels.grid_tiles, options.channels.anchor_covariances,
          options.channels.status}) {
      if (Status s = loop->Subscribe(channel, handler, options.queue_capacity); !s.ok()) {
        LogError(s.message());
        return 1;
      }
    }
  }
  loop->Every(std::chrono::milliseconds(options.push_period_ms), push);
  LcmLoop* bus = loop.get();
  auto status_line = [&] {
    std::ostringstream line;
    if (following) {
      line << "log events " << follower.events() << " (bytes skipped " << follower.bytes_skipped()
           << ", reopened " << follower.reopens() << ")";
    } else {
      line << "lcm messages " << bus->stats().messages_handled;
    }
    line << " | map update " << state.map_update() << ", " << state.num_trajectories()
         << " trajectories, " << state.num_keyframes() << " keyframes, " << state.num_tiles()
         << " tiles, seq " << state.seq() << ", restarts " << state.restarts() << " | "
         << web->StatusLine() << " | rejected: "
         << (node.rejections().total() + state.rejections().total() == 0
                 ? std::string("none")
                 : node.rejections().Summary() + " " + state.rejections().Summary());
    return line.str();
  };
  if (options.status_period_s > 0) {
    loop->Every(std::chrono::milliseconds(static_cast<int64_t>(1e3 * options.status_period_s)),
                [&] { LogInfo(status_line()); });
  }
  loop->StopOnSignals(
      [](int number) { LogInfo("signal " + std::to_string(number) + ": stopping"); });
  LogInfo("serving http://" + options.web.address + ":" + std::to_string(web->port()) + "/ (LCM " +
          (options.lcm_url.empty() ? std::string("default URL") : options.lcm_url) + ")");
  loop->Run();
  web->Stop();
  LogInfo("final: " + status_line());
  return 0;
}

int Main(int argc, char** argv) {
  ViewerOptions options;
  int max_queue_mb = static_cast<int>(options.web.max_client_queue_bytes >> 20);
  OptionsLoader loader("anchormap-viewer",
                       "[--lcm-url URL] [--http-address 127.0.0.1] [--http-port 8088] "
                       "[--config FILE] [options]",
                       "The live map in a browser: subscribes to anchormap-server's outputs and "
                       "serves a page\nthat draws the merged map, grid, anchors and status as "
                       "they change.");
  Register(&loader, &options, &max_queue_mb);
  const ParseOutcome outcome = loader.Parse(argc, argv);
  if (!outcome.run) return outcome.exit_code;
  Status valid;
  if (options.web.port < 0 || options.web.port > 65535)
    valid = Status::Error("--http-port: not a port");
  if (options.push_period_ms < 10 || options.push_period_ms > 60000)
    valid = Status::Error("--push-period-ms: 10 to 60000");
  if (max_queue_mb < 1 || max_queue_mb > 1024)
    valid = Status::Error("--max-client-queue-mb: 1 to 1024");
  if (options.web.max_clients < 1 || options.web.max_clients > 10000)
    valid = Status::Error("--max-clients: 1 to 10000");
  if (options.max_tiles < 1) valid = Status::Error("--max-tiles: at least 1");
  if (options.queue_capacity < 1) valid = Status::Error("--queue-capacity: at least 1");
  if (valid.ok()) valid = loader.StartLogging(options.log_level, "anchormap-viewer");
  if (!valid.ok()) return loader.UsageError(valid);
  options.web.max_client_queue_bytes = static_cast<size_t>(max_queue_mb) << 20;
  return Run(options);
}

}  // namespace
}  // namespace anchormap::viewer

int main(int argc, char** argv) { return anchormap::viewer::Main(argc, argv); }
