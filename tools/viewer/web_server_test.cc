#include "tools/viewer/web_server.h"

#include <future>
#include <thread>

#include <gtest/gtest.h>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>

namespace anchormap::viewer {
namespace {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;

// The server on its own thread, as in the viewer (one thread runs every handler); the
// test talks to it with a synchronous Beast client from the test's thread.
class ServerFixture {
 public:
  explicit ServerFixture(WebServerOptions options = {}) {
    options.port = 0;
    server_ = std::make_unique<WebServer>(io_, options, [this] {
      return std::make_shared<const std::string>("full-" + std::to_string(++fulls_));
    });
    const Status status = server_->Start();
    EXPECT_TRUE(status.ok()) << status.message();
    port_ = server_->port();
    thread_ = std::thread([this] { io_.run(); });
  }
  // Runs `f` on the server's thread and waits for it.
  template <typename F>
  auto OnServer(F f) {
    std::packaged_task<decltype(f())()> task(f);
    auto result = task.get_future();
    net::post(io_, [&task] { task(); });
    return result.get();
  }
  ~ServerFixture() {
    OnServer([this] {
      server_->Stop();
      return 0;
    });
    work_.reset();
    io_.stop();
    thread_.join();
    server_.reset();
  }
  WebServerStats Stats() {
    return OnServer([this] { return server_->stats(); });
  }
  void Broadcast(std::string text) {
    OnServer([this, text] {
      server_->Broadcast(std::make_shared<const std::string>(text));
      return 0;
    });
  }
  int port() const { return port_; }
  // The server's counts as soon as `done` holds of them, or after a bounded wait (5 s) as
  // they are then. A count changes on the server's thread after what it counts is visible
  // to the client: a write's bytes when its completion handler runs (the client may have
  // read them first), a refused frame right after its close frame, the wire bytes when TCP
  // acknowledges a little after a write completes.
  template <typename Done>
  WebServerStats StatsWhen(Done done) {
    WebServerStats stats = Stats();
    for (int i = 0; i < 5000 && !done(stats); ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
      stats = Stats();
    }
    return stats;
  }
  int64_t WireBytesAbove(int64_t floor) {
    return StatsWhen([floor](const WebServerStats& s) { return s.wire_bytes > floor; }).wire_bytes;
  }
  int64_t FramesRefused(int64_t expected) {
    return StatsWhen([expected](const WebServerStats& s) { return s.frames_refused >= expected; })
        .frames_refused;
  }

 private:
  net::io_context io_;
  net::executor_work_guard<net::io_context::executor_type> work_ = net::make_work_guard(io_);
  std::unique_ptr<WebServer> server_;
  std::thread thread_;
  int port_ = 0;
  int fulls_ = 0;  // used on the server's thread only
};

http::response<http::string_body> Request(int port, http::verb method, const std::string& target,
                                          const std::string& extra_header = "") {
  net::io_context io;
  beast::tcp_stream stream(io);
  stream.connect(tcp::endpoint(net::ip::make_address("127.0.0.1"), static_cast<uint16_t>(port)));
  http::request<http::string_body> request(method, target, 11);
  request.set(http::field::host, "127.0.0.1:" + std::to_string(port));
  if (!extra_header.empty()) request.set("X-Padding", extra_header);
  http::write(stream, request);
  beast::flat_buffer buffer;
  http::response<http::string_body> response;
  beast::error_code ec;
  http::read(stream, buffer, response, ec);
  return response;
}

struct Client {
  net::io_context io;
  websocket::stream<tcp::socket> ws{io};
  explicit Client(int port, const std::string& origin = "", bool deflate = false) {
    if (deflate) {
      websocket::permessage_deflate option;
      option.client_enable = true;
      ws.set_option(option);
    }
    net::connect(ws.next_layer(),
                 std::array<tcp::endpoint, 1>{tcp::endpoint(net::ip::make_address("127.0.0.1"),
                                                            static_cast<uint16_t>(port))});
    if (!origin.empty()) {
      ws.set_option(websocket::stream_base::decorator(
          [origin](websocket::request_type& r) { r.set(http::field::origin, origin); }));
    }
    ws.handshake("127.0.0.1:" + std::to_string(port), "/ws");
  }
  std::string Read() {
    beast::flat_buffer buffer;
    ws.read(buffer);
    return beast::buffers_to_string(buffer.data());
  }
  beast::error_code ReadError() {
    beast::flat_buffer buffer;
    beast::error_code ec;
    ws.read(buffer, ec);
    return ec;
  }
};

TEST(WebServerTest, ServesThePageItsScriptAndTheStateAndRefusesTheRest) {
  ServerFixture server;
  const auto page = Request(server.port(), http::verb::get, "/");
  EXPECT_EQ(page.result(), http::status::ok);
  EXPECT_NE(page.body().find("<script src=\"viewer.js\"></script>"), std::string::npos);
  EXPECT_EQ(page[http::field::content_type], "text/html; charset=utf-8");
  EXPECT_NE(page["Content-Security-Policy"].find("default-src 'none'"), beast::string_view::npos);
  const auto script = Request(server.port(), http::verb::get, "/viewer.js");
  EXPECT_EQ(script.result(), http::status::ok);
  EXPECT_NE(script.body().find("applyMessage"), std::string::npos);
  const auto state = Request(server.port(), http::verb::get, "/state.json");
  EXPECT_EQ(state.body(), "full-1");
  EXPECT_EQ(Request(server.port(), http::verb::get, "/etc/passwd").result(),
            http::status::not_found);
  EXPECT_EQ(Request(server.port(), http::verb::get, "/../viewer.js").result(),
            http::status::not_found);
  EXPECT_EQ(Request(server.port(), http::verb::post, "/").result(),
            http::status::method_not_allowed);
  // Headers over the 8 kB limit.
  EXPECT_EQ(Request(server.port(), http::verb::get, "/", std::string(9000, 'x')).result(),
            http::status::bad_request);
  const WebServerStats stats = server.Stats();
  EXPECT_EQ(stats.http_requests, 7);
  EXPECT_EQ(stats.http_refused, 4);
}

TEST(WebServerTest, AClientGetsTheFullStateThenTheBroadcastsAndALateOneTheFullStateOnce) {
  ServerFixture server;
  Client first(server.port());
  EXPECT_EQ(first.Read(), "full-1");
  first.ws.write(net::buffer(std::string(R"({"type":"hello"})")));
  server.Broadcast("delta-1");
  EXPECT_EQ(first.Read(), "delta-1");
  Client late(server.port());
  EXPECT_EQ(late.Read(), "full-2");
  server.Broadcast("delta-2");
  EXPECT_EQ(first.Read(), "delta-2");
  EXPECT_EQ(late.Read(), "delta-2");
  const WebServerStats stats =
      server.StatsWhen([](const WebServerStats& s) { return s.messages_sent >= 5; });
  EXPECT_EQ(stats.clients, 2);
  EXPECT_EQ(stats.messages_sent, 5);
  EXPECT_EQ(stats.bytes_sent, 6 + 7 + 6 + 7 + 7);
  EXPECT_EQ(stats.frames_refused, 0);
}

TEST(WebServerTest, MessagesAreCompressedForAClientThatOffersDeflate) {
  ServerFixture server;
  Client client(server.port(), "", /*deflate=*/true);
  EXPECT_EQ(client.Read(), "full-1");
  std::string tile;  // like a tile's base64 cells: long runs of one value
  for (int i = 0; i < 200000; ++i) tile += (i % 997 < 900) ? 'A' : static_cast<char>('a' + i % 26);
  server.Broadcast(tile);
  EXPECT_EQ(client.Read(), tile);
  EXPECT_EQ(server.StatsWhen([](const WebServerStats& s) { return s.bytes_sent >= 6 + 200000; })
                .bytes_sent,
            6 + 200000);
  const int64_t compressed = server.WireBytesAbove(6 + 200);  // the upgrade + the frames
  EXPECT_GT(compressed, 6 + 200);
  EXPECT_LT(compressed, 200000 / 4) << "not compressed";
  Client plain(server.port());  // one that does not offer it gets plain frames
  EXPECT_EQ(plain.Read(), "full-2");
  server.Broadcast(tile);
  EXPECT_EQ(plain.Read(), tile);
  EXPECT_EQ(client.Read(), tile);
  EXPECT_GT(server.WireBytesAbove(compressed + 200000), compressed + 200000);
}

TEST(WebServerTest, AnOversizeMessageClosesItsConnection) {
  WebServerOptions options;
  options.max_incoming_message_bytes = 1024;
  ServerFixture server(options);
  Client client(server.port());
  EXPECT_EQ(client.Read(), "full-1");
  client.ws.write(net::buffer(std::string(1025, 'a')));
  EXPECT_EQ(client.ReadError(), websocket::error::closed);
  EXPECT_EQ(client.ws.reason().code, websocket::close_code::too_big);
  EXPECT_EQ(server.FramesRefused(1), 1);
}

TEST(WebServerTest, AnythingButAHelloClosesItsConnection) {
  ServerFixture server;
  for (const std::string& text :
       {std::string("not json"), std::string(R"({"type":"run","cmd":"x"})"),
        std::string(R"({"type":"hello","extra":1})")}) {
    Client client(server.port());
    (void)client.Read();
    client.ws.write(net::buffer(text));
    EXPECT_EQ(client.ReadError(), websocket::error::closed) << text;
    EXPECT_EQ(client.ws.reason().code, websocket::close_code::policy_error) << text;
  }
  Client binary(server.port());
  (void)binary.Read();
  binary.ws.binary(true);
  binary.ws.write(net::buffer(std::string(R"({"type":"hello"})")));
  EXPECT_EQ(binary.ReadError(), websocket::error::closed);
  EXPECT_EQ(server.FramesRefused(4), 4);
}

TEST(WebServerTest, ACrossOriginUpgradeIsRefused) {
  ServerFixture server;
  EXPECT_THROW(Client(server.port(), "http://evil.example"), beast::system_error);
  Client same(server.port(), "http://127.0.0.1:" + std::to_string(server.port()));
  EXPECT_EQ(same.Read(), "full-1");  // the refused one never got a state
  EXPECT_EQ(server.Stats().http_refused, 1);
  EXPECT_EQ(server.Stats().clients_total, 1);
}

TEST(WebServerTest, ASlowClientsQueueStaysBoundedAndItResyncsWithAFullState) {
  WebServerOptions options;
  options.max_client_queue_bytes = 256 * 1024;
  ServerFixture server(options);
  Client slow(server.port());
  EXPECT_EQ(slow.Read(), "full-1");  // registered; from now on it reads nothing for a while
  const int kMessages = 1500;
  const std::string payload(32 * 1024, 'd');
  for (int i = 0; i < kMessages; ++i) server.Broadcast(std::to_string(i) + ":" + payload);
  const WebServerStats stats = server.Stats();
  EXPECT_GT(stats.messages_dropped, 0);
  EXPECT_GE(stats.resyncs, 1);
  // No more broadcasts: what is still to come is every delta not dropped and one full
  // state per resync. Deltas arrive in order, and a gap only ever follows a full state.
  const int64_t expected_deltas = kMessages - stats.messages_dropped;
  int64_t fulls = 0, deltas = 0;
  int last = -1;
  bool after_full = false;
  while (deltas + fulls < expected_deltas + stats.resyncs) {
    const std::string message = slow.Read();
    if (message.rfind("full-", 0) == 0) {
      ++fulls;
      after_full = true;
      continue;
    }
    const int index = std::stoi(message.substr(0, message.find(':')));
    if (after_full) {
      EXPECT_GT(index, last);
    } else {
      EXPECT_EQ(index, last + 1) << "a gap without a full state";
    }
    after_full = false;
    last = index;
    ++deltas;
  }
  EXPECT_EQ(fulls, stats.resyncs);
  EXPECT_EQ(deltas, expected_deltas);
  EXPECT_LT(deltas, kMessages);
  const int64_t sent = 1 + fulls + deltas;
  EXPECT_EQ(server.StatsWhen([sent](const WebServerStats& s) { return s.messages_sent >= sent; })
                .messages_sent,
            sent);
}

}  // namespace
}  // namespace anchormap::viewer
