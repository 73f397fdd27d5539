#pragma once
// The viewer's HTTP and WebSocket server (Boost.Beast), on the caller's io_context (one
// thread: handlers never overlap). Bus-free: it serves bytes it is given.
//   GET /, /index.html, /viewer.js   the page, from the files embedded at build time
//   GET /state.json                  the full state (the same JSON a new WebSocket gets)
//   GET /ws (WebSocket upgrade)      the full state once, then every Broadcast() message
// Everything else is refused: other paths 404, other methods 405, requests with a body or
// headers over the limit, and cross-origin WebSocket upgrades (an Origin that is not this
// host) 403. The page sends nothing the server acts on: a client may send a small text
// {"type": "hello"}; a larger, binary, non-JSON or other message closes its connection
// (counted). Each client's send queue is bounded: when a slow client's queue would pass
// the limit, its queued deltas are dropped (counted) and it gets the full state again as
// soon as its queue has drained, so its page stays correct and memory stays bounded.
// Messages are compressed (permessage-deflate) for clients that offer it.

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include <boost/asio/io_context.hpp>

#include "common/util/status.h"

namespace anchormap::viewer {

struct WebServerOptions {
  std::string address = "127.0.0.1";
  int port = 8088;                                  // 0: any free port (see port())
  size_t max_client_queue_bytes = 8 * 1024 * 1024;  // queued deltas per client
  size_t max_incoming_message_bytes = 1024;         // from a page (a hello is ~20 bytes)
  size_t max_request_header_bytes = 8 * 1024;
  int max_clients = 64;  // WebSocket clients at once; more are refused (503)
  // permessage-deflate when the browser offers it (all do): occupancy tiles and JSON
  // numbers compress several times over, for a little CPU per client.
  bool compress = true;
};

struct WebServerStats {
  int64_t clients = 0;        // WebSocket clients now
  int64_t clients_total = 0;  // accepted since start
  int64_t clients_refused = 0;
  int64_t http_requests = 0;
  int64_t http_refused = 0;      // 4xx / 5xx answers and unreadable requests
  int64_t messages_sent = 0;     // WebSocket messages written
  int64_t bytes_sent = 0;        // WebSocket payload bytes written (before compression)
  int64_t wire_bytes = 0;        // what the clients' TCP acknowledged (compressed, framed)
  int64_t frames_refused = 0;    // incoming messages that closed their connection
  int64_t messages_dropped = 0;  // deltas dropped for slow clients
  int64_t resyncs = 0;           // full states re-sent after drops
};

class WebServer {
 public:
  // Returns the full-state message: sent to each new client and on /state.json.
  using FullStateFn = std::function<std::shared_ptr<const std::string>()>;

  WebServer(boost::asio::io_context& io, WebServerOptions options, FullStateFn full_state);
  ~WebServer();
  WebServer(const WebServer&) = delete;
  WebServer& operator=(const WebServer&) = delete;

  // Binds and listens; an address that cannot be bound is an error, not an exception.
  Status Start();
  int port() const;  // the bound port (after Start)
  // Sends `message` (a text frame) to every WebSocket client.
  void Broadcast(std::shared_ptr<const std::string> message);
  // Stops accepting and closes every connection (the io_context finishes the rest).
  void Stop();
  const WebServerStats& stats() const;
  // "clients 2 (5 total) | sent 120 messages 3.4 MB | http 7 | refused ..." for status lines.
  std::string StatusLine() const;

  class Hub;  // shared with the sessions

 private:
  std::shared_ptr<Hub> hub_;
};

}  // namespace anchormap::viewer
