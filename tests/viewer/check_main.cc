// anchormap-test-viewer-check: checks what a browser showed (anchormap-test-viewer-browser's
// page state and screenshot) against the server's output log that was replayed through the
// viewer: the page holds the last merged map's trajectories with its keyframe counts, and
// in the screenshot each trajectory's colour is found at (most of) its keyframes' pixels.
// --same-as STATE also requires another page's trajectories (a late browser) to equal it.

#include <png.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <sstream>

#include <nlohmann/json.hpp>

#include "common/bus/lcm_log.h"
#include "common/bus/map_codec.h"
#include "common/bus/merged_map_assembler.h"
#include "common/io/graph_file.h"
#include "common/util/options_loader.h"
#include "tools/viewer/viewer_state.h"

namespace anchormap::viewer {
namespace {

using nlohmann::json;

struct Options {
  std::string map_log;
  std::string state;
  std::string screenshot;
  std::string same_as;
  std::string saved_prefix;
  bool print_last_update = false;
  int robots = 3;
  double min_color_fraction = 0.8;
};

struct Image {
  int width = 0, height = 0;
  std::vector<uint8_t> rgba;
  const uint8_t* At(int x, int y) const { return &rgba[4 * (static_cast<size_t>(y) * width + x)]; }
};

bool ReadPng(const std::string& path, Image* image) {
  png_image png;
  std::memset(&png, 0, sizeof(png));
  png.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&png, path.c_str())) return false;
  png.format = PNG_FORMAT_RGBA;
  image->width = static_cast<int>(png.width);
  image->height = static_cast<int>(png.height);
  image->rgba.resize(PNG_IMAGE_SIZE(png));
  return png_image_finish_read(&png, nullptr, image->rgba.data(), 0, nullptr) != 0;
}

std::optional<json> ReadJson(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  json value = json::parse(text.str(), nullptr, false);
  if (value.is_discarded()) return std::nullopt;
  return value;
}

int Fail(const std::string& message) {
  std::cerr << "viewer-check: FAIL: " << message << "\n";
  return 1;
}

int Run(const Options& o) {
  LcmLogReader reader;
  if (Status s = reader.Open(o.map_log); !s.ok()) return Fail(s.message());
  // The last complete merged map (header and chunks; one merged_map_t in older logs).
  MergedMapAssembler assembler;
  while (auto event = reader.Next()) {
    if (assembler.IsMapChannel(event->channel)) {
      (void)assembler.Accept(event->channel, event->data.data(), event->data.size());
    }
  }
  const std::optional<MergedMap>& last = assembler.map();
  if (!last) return Fail("no merged map in " + o.map_log);
  if (o.print_last_update) {
    std::cout << last->update << "\n";
    return 0;
  }
  const auto state = ReadJson(o.state);
  if (!state || !(*state)["trajectories"].is_array()) return Fail("no page state in " + o.state);
  const json& shown = (*state)["trajectories"];

  std::map<std::string, const MergedTrajectory*> expected;
  for (const MergedTrajectory& t : last->trajectories) {
    expected[TrajectoryKey(t.robot, t.trajectory_id)] = &t;
  }
  std::cout << "viewer-check: last merged map (update " << last->update << "): " << expected.size()
            << " trajectories; the page (map update " << (*state)["map_update"]
            << "): " << shown.size() << "\n";
  if (static_cast<int>(expected.size()) != o.robots) {
    return Fail("the log's last map has " + std::to_string(expected.size()) +
                " trajectories, not " + std::to_string(o.robots));
  }
  if (shown.size() != expected.size())
    return Fail("the page shows a different number of trajectories");
  for (const json& t : shown) {
    const auto it = expected.find(t["key"].get<std::string>());
    if (it == expected.end()) return Fail("the page shows " + t["key"].dump() + ", not in the map");
    const int64_t want = static_cast<int64_t>(it->second->poses.size());
    std::cout << "  " << t["key"].get<std::string>() << ": " << t["keyframes"]
              << " keyframes on the page, " << want << " in the map, colour " << t["color"].dump()
              << "\n";
    if (t["keyframes"].get<int64_t>() != want)
      return Fail("keyframe counts differ for " + t["key"].dump());
  }

  if (!o.same_as.empty()) {
    const auto other = ReadJson(o.same_as);
    if (!other) return Fail("no page state in " + o.same_as);
    for (const char* field : {"trajectories", "map_update", "encounters", "tiles", "seq"}) {
      json a = (*state)[field], b = (*other)[field];
      if (a != b)
        return Fail(std::string("the two pages differ in ") + field + ": " + a.dump() + " vs " +
                    b.dump());
    }
    std::cout << "viewer-check: both pages show the same trajectories, encounters and tiles\n";
  }

  if (!o.screenshot.empty()) {
    Image image;
    if (!ReadPng(o.screenshot, &image)) return Fail("cannot read " + o.screenshot);
    const json& view = (*state)["view"];
    const double scale = view["scale"], cx = view["cx"], cy = view["cy"];
    const double left = view["left"], top = view["top"], width = view["width"],
                 height = view["height"];
    for (const json& t : shown) {
      const MergedTrajectory& m = *expected[t["key"].get<std::string>()];
      const int r = t["color"][0], g = t["color"][1], b = t["color"][2];
      const double dx = t["offset"][0], dy = t["offset"][1];
      int found = 0, inside = 0;
      for (const Pose2& p : m.poses) {
        const int px = static_cast<int>(std::lround(left + width / 2 + (p.x() + dx - cx) * scale));
        const int py = static_cast<int>(std::lround(top + height / 2 - (p.y() + dy - cy) * scale));
        if (px < 1 || py < 1 || px >= image.width - 1 || py >= image.height - 1) continue;
        ++inside;
        bool hit = false;
        for (int oy = -1; oy <= 1 && !hit; ++oy) {
          for (int ox = -1; ox <= 1 && !hit; ++ox) {
            const uint8_t* c = image.At(px + ox, py + oy);
            hit = std::abs(c[0] - r) + std::abs(c[1] - g) + std::abs(c[2] - b) <= 30;
          }
        }
        found += hit;
      }
      const double fraction = inside ? static_cast<double>(found) / inside : 0.0;
      std::printf("  %s: its colour at %d of %d keyframe pixels (%.0f %%)\n",
                  t["key"].get<std::string>().c_str(), found, inside, 100 * fraction);
      if (inside < static_cast<int>(m.poses.size()) / 2)
        return Fail("most keyframes are off screen");
      if (fraction < o.min_color_fraction)
        return Fail("the trajectory's colour is missing at its poses");
    }
  }
  if (!o.saved_prefix.empty()) {
    // "Save g2o": a vertex per keyframe (trajectories in the page's order) at the map's
    // pose (rounded to 1 mm / 1e-4 rad by the viewer), an edge between consecutive
    // keyframes and one per encounter link.
    PoseGraph graph;
    if (Status s = ReadPoseGraph(o.saved_prefix + ".g2o", &graph); !s.ok())
      return Fail(s.message());
    size_t vertex = 0, edges = 0;
    for (const json& t : shown) {
      const MergedTrajectory& m = *expected[t["key"].get<std::string>()];
      for (const Pose2& p : m.poses) {
        if (vertex >= graph.vertices.size()) return Fail("the saved g2o has too few vertices");
        const Pose2& v = graph.vertices[vertex].pose;
        if (graph.vertices[vertex].id != static_cast<int64_t>(vertex) ||
            std::abs(v.x() - p.x()) > 6e-4 || std::abs(v.y() - p.y()) > 6e-4 ||
            std::abs(std::remainder(v.theta() - p.theta(), 2 * M_PI)) > 1e-4) {
          return Fail("saved vertex " + std::to_string(vertex) + " is not the map's pose");
        }
        ++vertex;
      }
      edges += m.poses.empty() ? 0 : m.poses.size() - 1;
    }
    edges += last->encounters.size();
    std::printf("viewer-check: saved g2o: %zu vertices, %zu edges (the map: %zu keyframes, %zu)\n",
                graph.vertices.size(), graph.edges.size(), vertex, edges);
    if (graph.vertices.size() != vertex || graph.edges.size() != edges) {
      return Fail("the saved g2o's vertex or edge count differs from the map's");
    }
    Image saved;
    if (!ReadPng(o.saved_prefix + ".png", &saved)) return Fail("the saved PNG does not read");
    const json& view = (*state)["view"];
    std::printf("viewer-check: saved PNG: %d x %d (the canvas: %s x %s)\n", saved.width,
                saved.height, view["width"].dump().c_str(), view["height"].dump().c_str());
    if (saved.width != view["width"].get<int>() || saved.height != view["height"].get<int>()) {
      return Fail("the saved PNG is not the canvas");
    }
  }
  std::cout << "viewer-check: PASS\n";
  return 0;
}

}  // namespace
}  // namespace anchormap::viewer

int main(int argc, char** argv) {
  anchormap::viewer::Options o;
  anchormap::OptionsLoader loader("anchormap-test-viewer-check", "--map LOG --state FILE [options]",
                                  "Checks a browser's view of anchormap-viewer (tests).");
  loader.Add("map", "map", &o.map_log, "the server-output log that was replayed", true);
  loader.Add("state", "state", &o.state, "the page's state (anchormap-test-viewer-browser)");
  loader.Add("print_last_update", "print-last-update", &o.print_last_update,
             "only print the last merged map's update number");
  loader.Add("screenshot", "screenshot", &o.screenshot, "the page's screenshot (PNG)");
  loader.Add("same_as", "same-as", &o.same_as, "another page's state that must show the same");
  loader.Add("saved_prefix", "saved", &o.saved_prefix,
             "PREFIX.png / PREFIX.g2o from the page's save buttons, to check");
  loader.Add("robots", "robots", &o.robots, "trajectories the last map must have");
  loader.Add("min_color_fraction", "min-color-fraction", &o.min_color_fraction,
             "keyframe pixels that must show their trajectory's colour");
  const anchormap::ParseOutcome outcome = loader.Parse(argc, argv);
  if (!outcome.run) return outcome.exit_code;
  return anchormap::viewer::Run(o);
}
