// anchormap-bench-scan-matching [--log CLF --relations REL] [--seed N]
//
// Prints matcher speed: local matches per second (keyframe to keyframe and scan to a local map
// of 10 scans) and global searches per second, on simulated 181-beam (180 degree) and 360-beam
// (full circle) scans in seeded rooms of 10-16 m by 8-12 m; then, on a CARMEN log (default:
// intel.clf.gz and intel.relations under $ANCHORMAP_DATA_DIR/benchmark or the build's data
// directory), scan-to-local-map odometry along the raw log: scans per second, matched /
// rejected counts, and the relations error (Kuemmerle et al. 2009) of raw odometry and of the
// refined trajectory; and global searches per second of the log's scans against a map of its
// first refined keyframes. Single-threaded; times are process CPU time (std::clock), so that
// a busy machine does not distort them.

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <random>
#include <string>
#include <vector>

#include "common/geometry/angle.h"
#include "common/scan_matching/correlative_matcher.h"
#include "common/scan_matching/global_search.h"
#include "common/scan_matching/local_map_matcher.h"
#include "tests/scan_testing/synthetic_world.h"
#include "tools/eval/relations.h"
#include "tools/import_carmen/carmen_import.h"

namespace anchormap {
namespace {

// Process CPU time, not wall time: the figures stay meaningful on a machine shared with other
// jobs (the program is single-threaded, so CPU time is its run time when it has a core).
struct Clock {
  using time_point = std::clock_t;
  static time_point now() { return std::clock(); }
};

double Seconds(Clock::time_point since) {
  return static_cast<double>(Clock::now() - since) / CLOCKS_PER_SEC;
}

struct Scene {
  PointCloud reference;               // keyframe in its body frame
  std::vector<PointCloud> local_map;  // 10 scans in the keyframe's frame
  PointCloud query;
  Pose2 truth;  // T_keyframe_query
  Pose2 guess;
};

// A random offset within +-translation_m and +-rotation_rad, one draw per statement: a call's
// argument order is unspecified, so Pose2(unit(rng), ...) would draw other scenes under clang
// than under gcc (gcc's order kept: theta, y, x).
Pose2 RandomOffset(double translation_m, double rotation_rad,
                   std::uniform_real_distribution<double>* unit, std::mt19937_64* rng) {
  const double theta = rotation_rad * (*unit)(*rng);
  const double y = translation_m * (*unit)(*rng);
  const double x = translation_m * (*unit)(*rng);
  return Pose2(x, y, theta);
}

void BenchSynthetic(const testing::SyntheticLaser& laser, const char* name, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::vector<Scene> scenes;
  std::vector<testing::SyntheticWorld> worlds;
  for (int i = 0; i < 50; ++i) {
    worlds.push_back(testing::RandomRoom(seed * 1000 + i));
    const testing::SyntheticWorld& world = worlds.back();
    Scene scene;
    const Pose2 a = testing::RandomFreePose(world, 0.8, &rng);
    Pose2 b;
    do {
      b = Compose(a, RandomOffset(0.3, 0.15, &unit, &rng));
    } while (world.DistanceToNearestWall(b.translation()) < 0.5);
    scene.truth = Between(a, b);
    scene.guess = Compose(scene.truth, RandomOffset(0.2, 0.1, &unit, &rng));
    scene.reference = ScanToPointCloud(testing::SimulateScan(world, laser, a, &rng));
    scene.query = ScanToPointCloud(testing::SimulateScan(world, laser, b, &rng));
    scene.local_map.push_back(scene.reference);
    for (int k = 1; k < 10; ++k) {
      // Nine more scans within 1.5 m of the keyframe, in free space.
      Pose2 c;
      do {
        c = Compose(a, RandomOffset(1.5, 0.3, &unit, &rng));
      } while (world.DistanceToNearestWall(c.translation()) < 0.3);
      scene.local_map.push_back(TransformPointCloud(
          ScanToPointCloud(testing::SimulateScan(world, laser, c, &rng)), Between(a, c)));
    }
    scenes.push_back(std::move(scene));
  }
  // Keyframe to keyframe: the reference built once per keyframe (timed apart).
  std::vector<ScanReference> references;
  auto start = Clock::now();
  for (const Scene& s : scenes)
    references.emplace_back(std::vector<PointCloud>{s.reference}, ScanReferenceOptions{});
  const double build_s = Seconds(start);
  double error_sum = 0.0;
  int matched = 0;
  start = Clock::now();
  for (size_t i = 0; i < scenes.size(); ++i) {
    const auto match = MatchLocal(references[i], scenes[i].query, scenes[i].guess, {});
    if (match) {
      ++matched;
      error_sum += PoseError(scenes[i].truth, match->pose).head<2>().norm();
    }
  }
  const double local_s = Seconds(start);
  std::printf(
      "%s: keyframe-to-keyframe: %.0f matches/s (window +-0.4 m, +-11.5 deg), reference "
      "build %.2f ms, %d/%zu matched, mean error %.4f m\n",
      name, scenes.size() / local_s, 1e3 * build_s / scenes.size(), matched, scenes.size(),
      matched ? error_sum / matched : 0.0);
  // Scan to a local map of 10 scans (4 max-grid levels, as LocalMapMatcher).
  ScanReferenceOptions local_options{0.05, 0.05, 0.5, 4};
  references.clear();
  start = Clock::now();
  for (const Scene& s : scenes) references.emplace_back(s.local_map, local_options);
  const double map_build_s = Seconds(start);
  start = Clock::now();
  matched = 0;
  error_sum = 0.0;
  for (size_t i = 0; i < scenes.size(); ++i) {
    const auto match = MatchLocal(references[i], scenes[i].query, scenes[i].guess, {});
    if (match) {
      ++matched;
      error_sum += PoseError(scenes[i].truth, match->pose).head<2>().norm();
    }
  }
  const double map_s = Seconds(start);
  std::printf(
      "%s: scan-to-local-map (10 scans): %.0f matches/s, map build %.2f ms, %d/%zu "
      "matched, mean error %.4f m\n",
      name, scenes.size() / map_s, 1e3 * map_build_s / scenes.size(), matched, scenes.size(),
      matched ? error_sum / matched : 0.0);
  // Global: the query against the room's map of 10 scans (the world frame), no prior.
  const int global_n = 10;
  std::vector<ScanReference> maps;
  std::vector<PointCloud> queries;
  std::vector<Pose2> truths;
  for (int i = 0; i < global_n; ++i) {
    const testing::SyntheticWorld& world = worlds[i];
    std::vector<PointCloud> map;
    for (int k = 0; k < 10; ++k) {
      const Pose2 p = testing::RandomFreePose(world, 0.8, &rng);
      map.push_back(
          TransformPointCloud(ScanToPointCloud(testing::SimulateScan(world, laser, p, &rng)), p));
    }
    maps.emplace_back(map, ScanReferenceOptions{});
    truths.push_back(testing::RandomFreePose(world, 0.8, &rng));
    queries.push_back(ScanToPointCloud(testing::SimulateScan(world, laser, truths.back(), &rng)));
  }
  start = Clock::now();
  int found = 0;
  for (int i = 0; i < global_n; ++i) {
    const auto match = GlobalSearch(maps[i], queries[i], GlobalSearchOptions{});
    if (match && PoseError(truths[i], match->pose).head<2>().norm() < 0.05) ++found;
  }
  const double global_s = Seconds(start);
  std::printf(
      "%s: global search (room map of 10 scans, full rotation): %.1f searches/s, %d/%d "
      "right within 5 cm\n",
      name, global_n / global_s, found, global_n);
}

LaserScan ToScan(const CarmenLaser& l, const Pose2& T_body_sensor) {
  LaserScan scan;
  scan.utime = static_cast<int64_t>(l.ipc_time_s * 1e6 + 0.5);
  scan.rad0 = static_cast<float>(l.start_angle_rad);
  scan.radstep = static_cast<float>(l.angular_resolution_rad);
  // FLASER carries no maximum range; SICK's no-return reading is 81.83 m.
  scan.max_range = static_cast<float>(l.max_range_m > 0.0 ? l.max_range_m : 80.0);
  scan.ranges = l.ranges_m;
  scan.T_body_sensor = T_body_sensor;
  return scan;
}

int BenchLog(const std::string& log_path, const std::string& relations_path) {
  CarmenLogContents contents;
  if (Status s = ReadCarmenLog(log_path, true, &contents); !s.ok()) {
    std::printf("%s: skipped (%s)\n", log_path.c_str(), s.ToString().c_str());
    return 0;
  }
  std::vector<Relation> relations;
  if (Status s = ReadRelationsFile(relations_path, &relations); !s.ok()) {
    std::printf("%s: skipped (%s)\n", relations_path.c_str(), s.ToString().c_str());
    return 0;
  }
  const Pose2 mounting = EstimateLaserMounting(contents);
  std::vector<PointCloud> clouds;
  for (const CarmenLaser& l : contents.lasers)
    clouds.push_back(ScanToPointCloud(ToScan(l, mounting)));

  LocalMapMatcher matcher(LocalMapMatcherOptions{});
  RelationsEstimate raw;
  RelationsEstimate refined;
  std::vector<std::pair<Pose2, size_t>> keyframes;  // refined pose, scan index
  const auto start = Clock::now();
  for (size_t i = 0; i < contents.lasers.size(); ++i) {
    const CarmenLaser& l = contents.lasers[i];
    const LocalMapUpdate update = matcher.AddScan(clouds[i], l.robot_pose);
    const int64_t utime = static_cast<int64_t>(l.ipc_time_s * 1e6 + 0.5);
    raw.poses.push_back({utime, l.robot_pose});
    refined.poses.push_back({utime, update.pose});
    if (update.keyframe) keyframes.push_back({update.pose, i});
  }
  const double seconds = Seconds(start);
  const double log_span_s = contents.lasers.back().ipc_time_s - contents.lasers.front().ipc_time_s;
  const LocalMapStats& stats = matcher.stats();
  std::printf(
      "%s: scan-to-local-map odometry: %zu scans in %.2f s = %.0f scans/s (%.0fx real "
      "time), %.2f ms/scan; matched %lld, rejected %lld, no match %lld, keyframes %lld, "
      "resets %lld; mounting (%.3f, %.3f, %.3f)\n",
      log_path.c_str(), contents.lasers.size(), seconds, contents.lasers.size() / seconds,
      log_span_s / seconds, 1e3 * seconds / contents.lasers.size(),
      static_cast<long long>(stats.matched), static_cast<long long>(stats.rejected),
      static_cast<long long>(stats.no_match), static_cast<long long>(stats.keyframes),
      static_cast<long long>(stats.resets), mounting.x(), mounting.y(), mounting.theta());
  for (const auto& [name, estimate] :
       {std::pair<const char*, const RelationsEstimate*>{"raw odometry", &raw},
        std::pair<const char*, const RelationsEstimate*>{"refined", &refined}}) {
    const RelationsResult r = EvaluateRelations(relations, *estimate, RelationsOptions{});
    std::printf(
        "  relations, %-12s: %lld of %lld evaluated, translation mean %.4f m (std %.4f), "
        "rotation mean %.3f deg (std %.3f)\n",
        name, static_cast<long long>(r.evaluated), static_cast<long long>(r.relations),
        r.translation_m.mean, r.translation_m.std, r.rotation_rad.mean / kPi * 180.0,
        r.rotation_rad.std / kPi * 180.0);
  }
  // Global: a map of the refined keyframes of the first quarter of the log (an Intel-sized
  // submap), queried with later scans that are inside the map's area; no prior.
  const size_t first_quarter = contents.lasers.size() / 4;
  std::vector<PointCloud> map;
  for (const auto& [pose, index] : keyframes) {
    if (index >= first_quarter) break;
    map.push_back(TransformPointCloud(clouds[index], pose));
  }
  const auto build_start = Clock::now();
  const ScanReference reference(map, ScanReferenceOptions{});
  const double build_s = Seconds(build_start);
  const GridGeometry& g = reference.geometry();
  int searches = 0;
  int scored = 0;
  int found = 0;
  const auto global_start = Clock::now();
  for (size_t i = first_quarter; i < contents.lasers.size() && searches < 20; i += 97) {
    ++searches;
    // The query cut at 15 m like the local map's: the angle step follows the farthest point.
    PointCloud query;
    for (const Eigen::Vector2d& p : clouds[i]) {
      if (p.norm() <= 15.0) query.push_back(p);
    }
    const auto match = GlobalSearch(reference, query, GlobalSearchOptions{});
    if (match) ++scored;
    if (match && PoseError(refined.poses[i].pose, match->pose).head<2>().norm() < 0.5) ++found;
  }
  const double global_s = Seconds(global_start);
  std::printf(
      "  global search against the first quarter's %zu keyframes (%.1f x %.1f m grid, built in "
      "%.0f ms): %.2f searches/s over %d later scans (points to 15 m); %d scored above 0.5, %d "
      "of them within 0.5 m of the refined odometry\n",
      map.size(), g.width * g.resolution, g.height * g.resolution, 1e3 * build_s,
      searches / global_s, searches, scored, found);
  return 0;
}

}  // namespace
}  // namespace anchormap

int main(int argc, char** argv) {
  std::setvbuf(stdout, nullptr, _IOLBF, 0);
  std::string data_dir = ANCHORMAP_DEFAULT_DATA_DIR;
  if (const char* env = std::getenv("ANCHORMAP_DATA_DIR")) data_dir = env;
  std::string log = data_dir + "/benchmark/intel.clf.gz";
  std::string relations = data_dir + "/benchmark/intel.relations";
  uint64_t seed = 1;
  bool synthetic = true;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--log" && i + 1 < argc) {
      log = argv[++i];
    } else if (arg == "--relations" && i + 1 < argc) {
      relations = argv[++i];
    } else if (arg == "--seed" && i + 1 < argc) {
      seed = std::strtoull(argv[++i], nullptr, 10);
    } else if (arg == "--no-synthetic") {
      synthetic = false;
    } else {
      std::fprintf(stderr,
                   "usage: anchormap-bench-scan-matching [--log CLF --relations REL] [--seed N] "
                   "[--no-synthetic]\n");
      return 2;
    }
  }
  if (synthetic) {
    anchormap::testing::SyntheticLaser half;
    half.beams = 181;
    half.fov_rad = anchormap::kPi;
    anchormap::testing::SyntheticLaser full;
    full.beams = 360;
    anchormap::BenchSynthetic(half, "181 beams, 180 deg", seed);
    anchormap::BenchSynthetic(full, "360 beams, 360 deg", seed);
  }
  return anchormap::BenchLog(log, relations);
}
