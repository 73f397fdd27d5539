#include "tools/viewer/web_server.h"

#include <cstdio>
#include <deque>
#include <optional>
#include <set>
#include <utility>
#include <vector>

#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <nlohmann/json.hpp>

#include "tools/viewer/tcp_bytes.h"
#include "tools/viewer/web_assets.h"

namespace anchormap::viewer {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;

namespace {

class WsSession;

}  // namespace

// State shared by the server and its sessions; sessions hold it weakly, so a session that
// outlives the server (its handlers still in the io_context) finds it gone and stops.
class WebServer::Hub {
 public:
  Hub(net::io_context& io, WebServerOptions options, FullStateFn full_state)
      : io(io), options(std::move(options)), full_state(std::move(full_state)), acceptor(io) {}
  net::io_context& io;
  WebServerOptions options;
  FullStateFn full_state;
  tcp::acceptor acceptor;
  WebServerStats stats;
  std::set<WsSession*> sessions;
  bool stopped = false;
};

namespace {

using Hub = WebServer::Hub;

bool OriginMatchesHost(beast::string_view origin, beast::string_view host) {
  if (origin.empty()) return true;  // not a browser, or a same-origin request that omits it
  const std::string expected_http = "http://" + std::string(host);
  return std::string(origin) == expected_http;
}

class WsSession : public std::enable_shared_from_this<WsSession> {
 public:
  WsSession(tcp::socket socket, const std::shared_ptr<Hub>& hub)
      : ws_(std::move(socket)), hub_(hub) {}
  ~WsSession() {
    if (registered_) {
      if (auto hub = hub_.lock()) {
        hub->sessions.erase(this);
        --hub->stats.clients;
      }
    }
  }

  void Accept(http::request<http::empty_body> request) {
    auto hub = hub_.lock();
    if (!hub) return;
    // The page only listens: Beast pings it (browsers answer) so that a quiet but live
    // connection is not taken for a dead one, and a dead one ends within a minute.
    websocket::stream_base::timeout timeout =
        websocket::stream_base::timeout::suggested(beast::role_type::server);
    timeout.idle_timeout = std::chrono::seconds(60);
    timeout.keep_alive_pings = true;
    ws_.set_option(timeout);
    ws_.read_message_max(hub->options.max_incoming_message_bytes);
    if (hub->options.compress) {
      websocket::permessage_deflate deflate;
      deflate.server_enable = true;
      deflate.compLevel = 3;  // most of the gain at a fraction of level 8's time
      ws_.set_option(deflate);
    }
    ws_.set_option(websocket::stream_base::decorator([](websocket::response_type& response) {
      response.set(http::field::server, "anchormap-viewer");
    }));
    ws_.async_accept(request,
                     [self = shared_from_this()](beast::error_code ec) { self->OnAccept(ec); });
  }

  void Send(std::shared_ptr<const std::string> message) {
    auto hub = hub_.lock();
    if (!hub || closing_) return;
    if (needs_full_) {  // a full state follows; deltas until then would be stale
      ++hub->stats.messages_dropped;
      return;
    }
    if (queued_bytes_ + message->size() > hub->options.max_client_queue_bytes && !queue_.empty()) {
      // Slow client: drop what waits (not the message being written) and resync.
      const size_t keep = writing_ ? 1 : 0;
      while (queue_.size() > keep) {
        queued_bytes_ -= queue_.back()->size();
        queue_.pop_back();
        ++hub->stats.messages_dropped;
      }
      ++hub->stats.messages_dropped;  // this one
      ++hub->stats.resyncs;
      needs_full_ = true;
      if (!writing_) SendFull(*hub);
      return;
    }
    Enqueue(std::move(message));
  }

  // Bytes on the wire so far: what the peer's TCP acknowledged (Linux's TCP_INFO).
  void CountWireBytes(Hub& hub) {
    const int64_t acked = TcpBytesAcked(beast::get_lowest_layer(ws_).socket().native_handle());
    if (acked > wire_bytes_counted_) {
      hub.stats.wire_bytes += acked - wire_bytes_counted_;
      wire_bytes_counted_ = acked;
    }
  }

  void Close() {
    if (closing_) return;
    closing_ = true;
    if (auto hub = hub_.lock()) CountWireBytes(*hub);
    beast::error_code ignored;
    beast::get_lowest_layer(ws_).socket().close(ignored);
  }

 private:
  void OnAccept(beast::error_code ec) {
    auto hub = hub_.lock();
    if (ec || !hub || hub->stopped) return;
    ws_.text(true);
    // The full state first (its provider may broadcast a pending delta, which this
    // session must not get: the full state includes it), then join the broadcasts.
    auto full = hub->full_state();
    hub->sessions.insert(this);
    registered_ = true;
    ++hub->stats.clients;
    ++hub->stats.clients_total;
    Enqueue(std::move(full));
    Read();
  }

  void SendFull(Hub& hub) {
    auto full = hub.full_state();  // a delta it broadcasts is dropped here: still needs_full_
    needs_full_ = false;
    Enqueue(std::move(full));
  }

  void Enqueue(std::shared_ptr<const std::string> message) {
    queued_bytes_ += message->size();
    queue_.push_back(std::move(message));
    if (!writing_) Write();
  }

  void Write() {
    writing_ = true;
    ws_.async_write(net::buffer(*queue_.front()),
                    [self = shared_from_this()](beast::error_code ec, size_t bytes) {
                      self->OnWrite(ec, bytes);
                    });
  }

  void OnWrite(beast::error_code ec, size_t bytes) {
    writing_ = false;
    auto hub = hub_.lock();
    if (ec || !hub) {
      Close();
      return;
    }
    ++hub->stats.messages_sent;
    hub->stats.bytes_sent += static_cast<int64_t>(bytes);
    CountWireBytes(*hub);
    queued_bytes_ -= queue_.front()->size();
    queue_.pop_front();
    if (needs_full_ && queue_.empty()) {
      SendFull(*hub);
    } else if (!queue_.empty()) {
      Write();
    }
  }

  void Read() {
    ws_.async_read(buffer_,
                   [self = shared_from_this()](beast::error_code ec, size_t) { self->OnRead(ec); });
  }

  void OnRead(beast::error_code ec) {
    auto hub = hub_.lock();
    if (!hub) return;
    if (ec == websocket::error::closed || ec == net::error::operation_aborted) return;
    if (ec) {  // oversize message, protocol violation, timeout, reset
      if (ec == websocket::error::message_too_big ||
          ec == websocket::condition::protocol_violation) {
        ++hub->stats.frames_refused;
      }
      Close();
      return;
    }
    bool hello = false;
    if (ws_.got_text()) {
      const std::string text = beast::buffers_to_string(buffer_.data());
      const nlohmann::json message =
          nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
      hello = message.is_object() && message.size() == 1 && message.contains("type") &&
              message["type"] == "hello";
    }
    buffer_.consume(buffer_.size());
    if (!hello) {
      ++hub->stats.frames_refused;
      closing_ = true;
      ws_.async_close(websocket::close_code::policy_error,
                      [self = shared_from_this()](beast::error_code) {});
      return;
    }
    Read();
  }

  websocket::stream<beast::tcp_stream> ws_;
  std::weak_ptr<Hub> hub_;
  beast::flat_buffer buffer_;
  std::deque<std::shared_ptr<const std::string>> queue_;
  size_t queued_bytes_ = 0;
  bool writing_ = false;
  bool needs_full_ = false;
  bool closing_ = false;
  bool registered_ = false;
  int64_t wire_bytes_counted_ = 0;
};

class HttpSession : public std::enable_shared_from_this<HttpSession> {
 public:
  HttpSession(tcp::socket socket, const std::shared_ptr<Hub>& hub)
      : stream_(std::move(socket)), hub_(hub) {}

  void Start() { Read(); }

 private:
  void Read() {
    auto hub = hub_.lock();
    if (!hub) return;
    parser_.emplace();
    parser_->header_limit(static_cast<std::uint32_t>(hub->options.max_request_header_bytes));
    stream_.expires_after(std::chrono::seconds(30));
    http::async_read(
        stream_, buffer_, *parser_,
        [self = shared_from_this()](beast::error_code ec, size_t) { self->OnRead(ec); });
  }

  void OnRead(beast::error_code ec) {
    auto hub = hub_.lock();
    if (!hub || hub->stopped) return;
    if (ec == http::error::end_of_stream || ec == net::error::operation_aborted ||
        ec == beast::error::timeout) {
      Shutdown();
      return;
    }
    ++hub->stats.http_requests;
    if (ec) {  // headers too large, a body, garbage
      ++hub->stats.http_refused;
      Respond(*hub, MakeResponse(http::status::bad_request, "text/plain", "bad request\n", 11),
              /*close=*/true);
      return;
    }
    const http::request<http::empty_body>& request = parser_->get();
    const std::string target(request.target());
    if (websocket::is_upgrade(request)) {
      if (target != "/ws") return Refuse(*hub, http::status::not_found, request);
      if (!OriginMatchesHost(request[http::field::origin], request[http::field::host])) {
        return Refuse(*hub, http::status::forbidden, request);
      }
      if (static_cast<int>(hub->sessions.size()) >= hub->options.max_clients) {
        ++hub->stats.clients_refused;
        return Refuse(*hub, http::status::service_unavailable, request);
      }
      stream_.expires_never();
      std::make_shared<WsSession>(stream_.release_socket(), hub)->Accept(parser_->release());
      return;
    }
    if (request.method() != http::verb::get) {
      return Refuse(*hub, http::status::method_not_allowed, request);
    }
    const auto& files = EmbeddedFiles();
    std::string name = target == "/" ? "index.html" : target.substr(1);
    if (target == "/state.json") {
      const auto state = hub->full_state();
      return Respond(*hub,
                     MakeResponse(http::status::ok, "application/json", *state, request.version()),
                     !request.keep_alive());
    }
    const auto file = files.find(name);
    if (target.empty() || target[0] != '/' || file == files.end()) {
      return Refuse(*hub, http::status::not_found, request);
    }
    const bool html = name.size() > 5 && name.compare(name.size() - 5, 5, ".html") == 0;
    Respond(*hub,
            MakeResponse(http::status::ok,
                         html ? "text/html; charset=utf-8" : "text/javascript; charset=utf-8",
                         std::string(file->second), request.version()),
            !request.keep_alive());
  }

  static http::response<http::string_body> MakeResponse(http::status status,
                                                        const std::string& type, std::string body,
                                                        unsigned version) {
    http::response<http::string_body> response(status, version);
    response.set(http::field::server, "anchormap-viewer");
    response.set(http::field::content_type, type);
    response.set(http::field::cache_control, "no-store");
    response.set("X-Content-Type-Options", "nosniff");
    response.set("Content-Security-Policy",
                 "default-src 'none'; script-src 'self'; style-src 'unsafe-inline'; "
                 "connect-src 'self'; img-src 'self' blob: data:");
    response.body() = std::move(body);
    response.prepare_payload();
    return response;
  }

  void Refuse(Hub& hub, http::status status, const http::request<http::empty_body>& request) {
    ++hub.stats.http_refused;
    const std::string text = std::string(http::obsolete_reason(status)) + "\n";
    Respond(hub, MakeResponse(status, "text/plain", text, request.version()), true);
  }

  void Respond(Hub&, http::response<http::string_body> response, bool close) {
    response.keep_alive(!close);
    response_ = std::make_shared<http::response<http::string_body>>(std::move(response));
    http::async_write(stream_, *response_,
                      [self = shared_from_this(), close](beast::error_code ec, size_t) {
                        if (ec || close) return self->Shutdown();
                        self->Read();
                      });
  }

  void Shutdown() {
    beast::error_code ignored;
    stream_.socket().shutdown(tcp::socket::shutdown_send, ignored);
  }

  beast::tcp_stream stream_;
  std::weak_ptr<Hub> hub_;
  beast::flat_buffer buffer_{8192};
  std::optional<http::request_parser<http::empty_body>> parser_;
  std::shared_ptr<http::response<http::string_body>> response_;
};

void Accept(const std::shared_ptr<Hub>& hub) {
  hub->acceptor.async_accept(
      [weak = std::weak_ptr<Hub>(hub)](beast::error_code ec, tcp::socket socket) {
        auto hub = weak.lock();
        if (!hub || hub->stopped) return;
        if (!ec) std::make_shared<HttpSession>(std::move(socket), hub)->Start();
        Accept(hub);
      });
}

}  // namespace

WebServer::WebServer(net::io_context& io, WebServerOptions options, FullStateFn full_state)
    : hub_(std::make_shared<Hub>(io, std::move(options), std::move(full_state))) {}

WebServer::~WebServer() { Stop(); }

Status WebServer::Start() {
  beast::error_code ec;
  const auto address = net::ip::make_address(hub_->options.address, ec);
  if (ec) return Status::Error("--http-address '" + hub_->options.address + "': " + ec.message());
  if (hub_->options.port < 0 || hub_->options.port > 65535) {
    return Status::Error("--http-port " + std::to_string(hub_->options.port) + " is not a port");
  }
  const tcp::endpoint endpoint(address, static_cast<unsigned short>(hub_->options.port));
  tcp::acceptor& acceptor = hub_->acceptor;
  if (acceptor.open(endpoint.protocol(), ec); ec) {
    return Status::Error(ErrorCode::kIoError, "cannot open a socket: " + ec.message());
  }
  if (acceptor.set_option(net::socket_base::reuse_address(true), ec); ec) {
    return Status::Error(ErrorCode::kIoError, "SO_REUSEADDR: " + ec.message());
  }
  if (acceptor.bind(endpoint, ec); ec) {
    return Status::Error(ErrorCode::kIoError, "cannot bind " + hub_->options.address + ":" +
                                                  std::to_string(hub_->options.port) + ": " +
                                                  ec.message());
  }
  if (acceptor.listen(net::socket_base::max_listen_connections, ec); ec) {
    return Status::Error(ErrorCode::kIoError, "listen: " + ec.message());
  }
  Accept(hub_);
  return Status::Ok();
}

int WebServer::port() const {
  beast::error_code ec;
  const auto endpoint = hub_->acceptor.local_endpoint(ec);
  return ec ? -1 : endpoint.port();
}

void WebServer::Broadcast(std::shared_ptr<const std::string> message) {
  // Copy: a send that fails can close (not erase) a session, but stay safe anyway.
  const std::vector<WsSession*> sessions(hub_->sessions.begin(), hub_->sessions.end());
  for (WsSession* session : sessions) {
    if (hub_->sessions.count(session)) session->Send(message);
  }
}

void WebServer::Stop() {
  if (hub_->stopped) return;
  hub_->stopped = true;
  beast::error_code ignored;
  hub_->acceptor.close(ignored);
  for (WsSession* session : hub_->sessions) session->Close();
}

const WebServerStats& WebServer::stats() const {
  for (WsSession* session : hub_->sessions) session->CountWireBytes(*hub_);
  return hub_->stats;
}

std::string WebServer::StatusLine() const {
  const WebServerStats& s = stats();
  char text[400];
  std::snprintf(
      text, sizeof(text),
      "clients %lld (%lld total, %lld refused) | sent %lld messages %.2f MB (%.2f MB on the "
      "wire) | http %lld "
      "(%lld refused) | frames refused %lld | slow clients: %lld dropped, %lld resyncs",
      static_cast<long long>(s.clients), static_cast<long long>(s.clients_total),
      static_cast<long long>(s.clients_refused), static_cast<long long>(s.messages_sent),
      static_cast<double>(s.bytes_sent) / 1e6, static_cast<double>(s.wire_bytes) / 1e6,
      static_cast<long long>(s.http_requests), static_cast<long long>(s.http_refused),
      static_cast<long long>(s.frames_refused), static_cast<long long>(s.messages_dropped),
      static_cast<long long>(s.resyncs));
  return text;
}

}  // namespace anchormap::viewer
