// anchormap-test-viewer-browser: drives a headless Chromium through its DevTools protocol
// (a WebSocket on --devtools-port) for viewer_browser_test.sh. Waits until the page shows
// what the viewer holds (the page's seq equals /state.json's, and its map update is at
// least --min-map-update), then writes the page's own state (window.anchormapViewer.state())
// and a screenshot. The waits are bounded (--timeout-s); a page that never catches up is
// an error, not a skip.

#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <thread>

#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <nlohmann/json.hpp>

#include "common/util/options_loader.h"
#include "tools/viewer/base64.h"

namespace anchormap::viewer {
namespace {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;
using nlohmann::json;

struct Options {
  int devtools_port = 0;
  int viewer_port = 0;
  int64_t min_map_update = 0;
  double timeout_s = 60;
  std::string state_out;
  std::string screenshot_out;
  std::string save_prefix;
  int draw_times = 0;
};

// What the page's "Save PNG" button downloads, as base64 (in chunks: a large spread
// would overflow the call stack).
constexpr char kSavedPngExpression[] = R"js(
window.anchormapViewer.pngBlob().then((blob) => blob.arrayBuffer()).then((buffer) => {
  const bytes = new Uint8Array(buffer);
  let text = '';
  for (let i = 0; i < bytes.length; i += 8192) {
    text += String.fromCharCode.apply(null, bytes.subarray(i, i + 8192));
  }
  return btoa(text);
}))js";

// GET http://127.0.0.1:port/target; "" when anything fails.
std::string HttpGet(int port, const std::string& target) {
  try {
    net::io_context io;
    beast::tcp_stream stream(io);
    stream.expires_after(std::chrono::seconds(10));
    stream.connect(tcp::endpoint(net::ip::make_address("127.0.0.1"), static_cast<uint16_t>(port)));
    http::request<http::empty_body> request(http::verb::get, target, 11);
    request.set(http::field::host, "127.0.0.1:" + std::to_string(port));
    http::write(stream, request);
    beast::flat_buffer buffer;
    http::response<http::string_body> response;
    http::read(stream, buffer, response);
    return response.result() == http::status::ok ? response.body() : "";
  } catch (const std::exception&) {
    return "";
  }
}

class DevTools {
 public:
  // Connects to the first page target's WebSocket.
  bool Connect(int port, const std::string& url_prefix) {
    const json targets = json::parse(HttpGet(port, "/json/list"), nullptr, false);
    if (!targets.is_array()) return false;
    for (const json& t : targets) {
      if (t.value("type", "") != "page" || t.value("url", "").rfind(url_prefix, 0) != 0) continue;
      const std::string ws_url = t.value("webSocketDebuggerUrl", "");
      const size_t path = ws_url.find("/devtools/");
      if (path == std::string::npos) continue;
      try {
        net::connect(ws_.next_layer(),
                     std::array<tcp::endpoint, 1>{tcp::endpoint(net::ip::make_address("127.0.0.1"),
                                                                static_cast<uint16_t>(port))});
        ws_.read_message_max(64 << 20);
        ws_.handshake("127.0.0.1:" + std::to_string(port), ws_url.substr(path));
        return true;
      } catch (const std::exception&) {
        return false;
      }
    }
    return false;
  }
  // Sends a command and returns its "result" (events in between are skipped).
  json Call(const std::string& method, const json& params) {
    const int id = ++id_;
    ws_.write(net::buffer(json({{"id", id}, {"method", method}, {"params", params}}).dump()));
    while (true) {
      beast::flat_buffer buffer;
      ws_.read(buffer);
      const json reply = json::parse(beast::buffers_to_string(buffer.data()), nullptr, false);
      if (reply.is_object() && reply.value("id", -1) == id) return reply.value("result", json());
    }
  }
  json Evaluate(const std::string& expression, bool await_promise = false) {
    const json result = Call(
        "Runtime.evaluate",
        {{"expression", expression}, {"returnByValue", true}, {"awaitPromise", await_promise}});
    return result.is_object() && result.contains("result") ? result["result"].value("value", json())
                                                           : json();
  }

 private:
  net::io_context io_;
  websocket::stream<tcp::socket> ws_{io_};
  int id_ = 0;
};

int Run(const Options& o) {
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::milliseconds(static_cast<int64_t>(1e3 * o.timeout_s));
  const std::string page_url = "http://127.0.0.1:" + std::to_string(o.viewer_port) + "/";
  DevTools devtools;
  while (!devtools.Connect(o.devtools_port, page_url)) {
    if (std::chrono::steady_clock::now() > deadline) {
      std::cerr << "viewer-browser: no DevTools page for " << page_url << " on port "
                << o.devtools_port << "\n";
      return 1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  json state;
  int64_t viewer_seq = -1;
  while (true) {
    const json viewer = json::parse(HttpGet(o.viewer_port, "/state.json"), nullptr, false);
    if (viewer.is_object()) viewer_seq = viewer.value("seq", int64_t{-1});
    const json text = devtools.Evaluate(
        "window.anchormapViewer ? (window.anchormapViewer.draw(), "
        "JSON.stringify(window.anchormapViewer.state())) : ''");
    state = text.is_string() ? json::parse(text.get<std::string>(), nullptr, false) : json();
    if (state.is_object() && state.value("seq", int64_t{-2}) == viewer_seq &&
        state.value("map_update", int64_t{-1}) >= o.min_map_update) {
      break;
    }
    if (std::chrono::steady_clock::now() > deadline) {
      std::cerr << "viewer-browser: the page did not reach map update " << o.min_map_update
                << " and the viewer's seq " << viewer_seq << " in " << o.timeout_s
                << " s; its state: " << (state.is_object() ? state.dump() : "none") << "\n";
      return 1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(250));
  }
  std::ofstream(o.state_out) << state.dump(1) << "\n";
  if (!o.screenshot_out.empty()) {
    const json shot = devtools.Call("Page.captureScreenshot", {{"format", "png"}});
    const auto png = Base64Decode(shot.is_object() ? shot.value("data", "") : "");
    if (!png || png->empty()) {
      std::cerr << "viewer-browser: no screenshot\n";
      return 1;
    }
    std::ofstream(o.screenshot_out, std::ios::binary)
        .write(reinterpret_cast<const char*>(png->data()),
               static_cast<std::streamsize>(png->size()));
  }
  if (!o.save_prefix.empty()) {  // what the save buttons give
    const json g2o = devtools.Evaluate("window.anchormapViewer.g2o()");
    const json png = devtools.Evaluate(kSavedPngExpression, /*await_promise=*/true);
    const auto png_bytes = Base64Decode(png.is_string() ? png.get<std::string>() : "");
    if (!g2o.is_string() || !png_bytes || png_bytes->empty()) {
      std::cerr << "viewer-browser: the page's save functions gave nothing\n";
      return 1;
    }
    std::ofstream(o.save_prefix + ".g2o") << g2o.get<std::string>();
    std::ofstream(o.save_prefix + ".png", std::ios::binary)
        .write(reinterpret_cast<const char*>(png_bytes->data()),
               static_cast<std::streamsize>(png_bytes->size()));
  }
  if (o.draw_times > 0) {  // the page's frame time with everything drawn, N times
    // One draw per animation frame, as the page draws (back-to-back draws in one task
    // would also time the raster of the previous one).
    const json times = devtools.Evaluate(
        "new Promise((resolve) => { const t = []; const step = () => { "
        "const s = performance.now(); window.anchormapViewer.draw(); "
        "t.push(performance.now() - s); if (t.length < " +
            std::to_string(o.draw_times) +
            ") { requestAnimationFrame(step); } else { t.sort((a, b) => a - b); resolve(t); } }; "
            "requestAnimationFrame(step); })",
        /*await_promise=*/true);
    if (times.is_array() && !times.empty()) {
      std::printf(
          "viewer-browser: draw() with everything, one per animation frame: median %.1f ms, min "
          "%.1f, max %.1f over %zu "
          "draws\n",
          times[times.size() / 2].get<double>(), times.front().get<double>(),
          times.back().get<double>(), times.size());
    }
  }
  std::cout << "viewer-browser: page seq " << state["seq"] << ", map update " << state["map_update"]
            << ", " << state["trajectories"].size() << " trajectories, " << state["fulls"]
            << " full states and " << state["deltas"] << " deltas received\n";
  return 0;
}

}  // namespace
}  // namespace anchormap::viewer

int main(int argc, char** argv) {
  anchormap::viewer::Options o;
  anchormap::OptionsLoader loader("anchormap-test-viewer-browser",
                                  "--devtools-port P --viewer-port P --state-out FILE",
                                  "Reads a headless Chromium page's viewer state (tests).");
  loader.Add("devtools_port", "devtools-port", &o.devtools_port, "Chromium's DevTools port", true);
  loader.Add("viewer_port", "viewer-port", &o.viewer_port, "anchormap-viewer's HTTP port", true);
  loader.Add("min_map_update", "min-map-update", &o.min_map_update, "wait for this map update");
  loader.Add("timeout_s", "timeout-s", &o.timeout_s, "give up after this long (s)");
  loader.Add("state_out", "state-out", &o.state_out, "write the page's state here", true);
  loader.Add("screenshot_out", "screenshot-out", &o.screenshot_out, "write a PNG screenshot here");
  loader.Add("save_prefix", "save-prefix", &o.save_prefix,
             "write what the page's save buttons give to PREFIX.png and PREFIX.g2o");
  loader.Add("draw_times", "draw-times", &o.draw_times,
             "time the page's draw() this many times at the end (benchmark)");
  const anchormap::ParseOutcome outcome = loader.Parse(argc, argv);
  if (!outcome.run) return outcome.exit_code;
  return anchormap::viewer::Run(o);
}
