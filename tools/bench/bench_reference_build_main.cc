// anchormap-bench-reference-build [--robots N] [--duration-s S] [--seed N]
//
// The scan references the server builds for its searches (ScanReference: the reference
// field, the likelihood grid, the max-grids as bytes), on submaps of a simulated team: the
// simulator's robots (office world, anchormap-sim's options) give a keyframe every
// --keyframe-period-s each; every --stride-th keyframe of a robot is the centre of a submap
// of the --half-width keyframes on either side (their scans at their true poses, returns within
// --max-range-m, as the scan encounters' near submaps). Each submap is built --passes times;
// prints the CPU ms per build of the reference (field and likelihood) and of its byte
// max-grids (ScanReference::byte_bounds, what the searches bound on), the least of the passes,
// and a hash of every build's likelihood and bytes (the same inputs must give the same hash
// whatever the implementation).
// Single-threaded.

#include <malloc.h>
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <ctime>
#include <limits>
#include <memory>
#include <vector>

#include <boost/program_options.hpp>

#include "common/scan_matching/byte_max_grids.h"
#include "common/scan_matching/point_cloud.h"
#include "common/scan_matching/scan_reference.h"
#include "tools/bench/simulated_keyframes.h"

namespace anchormap {
namespace {

double CpuSeconds() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }

void MixReference(const ScanReference& reference, const ByteMaxGrids* bytes, Fnv1aHash* hash) {
  const MaxGridPyramid::LevelView base = reference.base().level(0);
  hash->Mix(static_cast<uint64_t>(base.width));
  hash->Mix(static_cast<uint64_t>(base.height));
  const size_t cells = static_cast<size_t>(base.width) * static_cast<size_t>(base.height);
  for (size_t i = 0; i < cells; ++i) {
    uint32_t bits = 0;
    static_assert(sizeof(float) == sizeof(bits));
    __builtin_memcpy(&bits, &base.values[i], sizeof(bits));
    hash->Mix(bits);
  }
  if (bytes == nullptr) return;
  for (int h = 1; h < bytes->num_levels(); ++h) {
    const ByteMaxGrids::LevelView level = bytes->level(h);
    const size_t n = static_cast<size_t>(level.width) * static_cast<size_t>(level.height);
    for (size_t i = 0; i < n; ++i) hash->Mix(level.values[i]);
  }
}

int Run(int argc, char** argv) {
  // The server's heap reuses its freed arrays (glibc raises its mmap threshold as big blocks
  // are freed); the bench's builds would otherwise each map and fault in fresh pages.
  mallopt(M_MMAP_THRESHOLD, 256 << 20);
  mallopt(M_TRIM_THRESHOLD, 512 << 20);
  namespace po = boost::program_options;
  sim::SimOptions sim_options;
  sim_options.robots = 20;
  sim_options.duration_s = 60.0;
  sim_options.seed = 2;
  double keyframe_period_s = 0.67;
  int half_width = 5;
  int stride = 3;
  double max_range_m = 15.0;
  int passes = 3;
  po::options_description desc("anchormap-bench-reference-build");
  desc.add_options()("help", "this help")(
      "robots", po::value(&sim_options.robots)->default_value(sim_options.robots), "robots")(
      "duration-s", po::value(&sim_options.duration_s)->default_value(sim_options.duration_s),
      "simulated seconds")("seed", po::value(&sim_options.seed)->default_value(sim_options.seed),
                           "simulator seed")(
      "keyframe-period-s", po::value(&keyframe_period_s)->default_value(keyframe_period_s),
      "a keyframe per robot this often")("half-width",
                                         po::value(&half_width)->default_value(half_width),
                                         "keyframes on either side of a submap's centre")(
      "stride", po::value(&stride)->default_value(stride), "a submap every this many keyframes")(
      "max-range-m", po::value(&max_range_m)->default_value(max_range_m),
      "returns farther from the sensor are left out")(
      "passes", po::value(&passes)->default_value(passes), "builds of every submap");
  po::variables_map vm;
  po::store(po::parse_command_line(argc, argv, desc), vm);
  po::notify(vm);
  if (vm.count("help")) {
    std::printf("%s", "see the comment at the top of bench_reference_build_main.cc\n");
    return 0;
  }
  if (half_width < 0 || stride < 1 || passes < 1) {
    std::fprintf(stderr, "--half-width must be >= 0, --stride and --passes >= 1\n");
    return 1;
  }
  std::vector<SimulatedKeyframe> simulated;
  if (const Status status = SimulateKeyframes(sim_options, keyframe_period_s, &simulated);
      !status.ok()) {
    std::fprintf(stderr, "%s\n", status.message().c_str());
    return 1;
  }
  // Per robot, its keyframes' body-frame points and true poses.
  struct Keyframe {
    PointCloud points;
    Pose2 pose;
  };
  std::vector<std::vector<Keyframe>> robots(static_cast<size_t>(sim_options.robots));
  for (const SimulatedKeyframe& k : simulated) {
    robots[static_cast<size_t>(k.robot)].push_back(
        {ScanToPointCloud(k.scan, max_range_m), k.T_world_body});
  }
  // The submaps: each keyframe's points in its centre's frame.
  std::vector<std::vector<PointCloud>> submaps;
  size_t points = 0;
  for (const std::vector<Keyframe>& keyframes : robots) {
    const int n = static_cast<int>(keyframes.size());
    for (int centre = 0; centre < n; centre += stride) {
      std::vector<PointCloud>& scans = submaps.emplace_back();
      const Pose2& T_world_centre = keyframes[static_cast<size_t>(centre)].pose;
      for (int i = std::max(0, centre - half_width); i <= std::min(n - 1, centre + half_width);
           ++i) {
        const Keyframe& k = keyframes[static_cast<size_t>(i)];
        scans.push_back(TransformPointCloud(k.points, Between(T_world_centre, k.pose)));
        points += scans.back().size();
      }
    }
  }
  std::printf(
      "submaps %zu, %.0f points per submap\n", submaps.size(),
      static_cast<double>(points) / static_cast<double>(std::max<size_t>(submaps.size(), 1)));
  const ScanReferenceOptions options;
  double best_build = std::numeric_limits<double>::infinity();
  double best_bytes = best_build;
  Fnv1aHash hash;
  for (int pass = 0; pass < passes; ++pass) {
    double build_s = 0.0, bytes_s = 0.0;
    for (const std::vector<PointCloud>& scans : submaps) {
      double start = CpuSeconds();
      const ScanReference reference(scans, options);
      build_s += CpuSeconds() - start;
      start = CpuSeconds();
      const ByteMaxGrids* bytes = reference.byte_bounds();
      bytes_s += CpuSeconds() - start;
      if (pass == 0) MixReference(reference, bytes, &hash);
    }
    best_build = std::min(best_build, build_s);
    best_bytes = std::min(best_bytes, bytes_s);
  }
  const double per_build_ms = 1e3 / static_cast<double>(std::max<size_t>(submaps.size(), 1));
  std::printf("reference (field, likelihood): %.3f ms per build\n", best_build * per_build_ms);
  std::printf("byte max-grids:                %.3f ms per build\n", best_bytes * per_build_ms);
  std::printf("hash %016llx\n", static_cast<unsigned long long>(hash.value));
  return 0;
}

}  // namespace
}  // namespace anchormap

int main(int argc, char** argv) { return anchormap::Run(argc, argv); }
