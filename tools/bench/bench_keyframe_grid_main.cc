// anchormap-bench-keyframe-grid [--robots N] [--duration-s S] [--seed N]
//
// The server's occupancy grid (KeyframeGrid) under the load a team gives it, without the rest
// of the server: the simulator's robots (office world, the same options as anchormap-sim) give
// a keyframe every --keyframe-period-s each (true pose, scan); every --period-s of data a
// "publication" traces in the new keyframes and traces again --moved placed keyframes whose
// pose moved by a few cells (random, the farthest first, as MapPublisher::UpdateGrid takes
// them); the end moves every keyframe and places them all (the offline replay's complete grid).
// Prints process CPU seconds per phase, the traces, and a hash of the final tiles (the same
// inputs must give the same hash whatever the grid's implementation). Single-threaded.

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <ctime>
#include <memory>
#include <random>
#include <vector>

#include <boost/program_options.hpp>

#include "common/scan/keyframe_grid.h"
#include "tools/bench/simulated_keyframes.h"

namespace anchormap {
namespace {

double CpuSeconds() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }

uint64_t HashTiles(const std::vector<GridTile>& tiles) {
  Fnv1aHash hash;
  for (const GridTile& tile : tiles) {
    hash.Mix(static_cast<uint64_t>(tile.tile_x));
    hash.Mix(static_cast<uint64_t>(tile.tile_y));
    for (int8_t c : tile.cells) hash.Mix(static_cast<uint8_t>(c));
  }
  return hash.value;
}

int Run(int argc, char** argv) {
  namespace po = boost::program_options;
  sim::SimOptions sim_options;
  sim_options.robots = 100;
  sim_options.duration_s = 180.0;
  sim_options.seed = 2;
  double keyframe_period_s = 0.67;
  double period_s = 5.0;
  int moved_per_period = 1000;
  double shift_m = 0.15;
  po::options_description desc("anchormap-bench-keyframe-grid");
  desc.add_options()("help", "this help")(
      "robots", po::value(&sim_options.robots)->default_value(sim_options.robots), "robots")(
      "duration-s", po::value(&sim_options.duration_s)->default_value(sim_options.duration_s),
      "simulated seconds")("seed", po::value(&sim_options.seed)->default_value(sim_options.seed),
                           "simulator seed")(
      "keyframe-period-s", po::value(&keyframe_period_s)->default_value(keyframe_period_s),
      "a keyframe per robot this often")("period-s", po::value(&period_s)->default_value(period_s),
                                         "grid publications this often")(
      "moved", po::value(&moved_per_period)->default_value(moved_per_period),
      "keyframes traced again per publication")(
      "shift-m", po::value(&shift_m)->default_value(shift_m), "a move's largest shift");
  po::variables_map vm;
  po::store(po::parse_command_line(argc, argv, desc), vm);
  po::notify(vm);
  if (vm.count("help")) {
    std::printf("%s", "see the comment at the top of bench_keyframe_grid_main.cc\n");
    return 0;
  }
  std::vector<SimulatedKeyframe> keyframes;
  if (const Status status = SimulateKeyframes(sim_options, keyframe_period_s, &keyframes);
      !status.ok()) {
    std::fprintf(stderr, "%s\n", status.message().c_str());
    return 1;
  }
  std::printf("keyframes %zu\n", keyframes.size());

  KeyframeGrid grid;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::vector<Pose2> estimate;
  auto shifted = [&](const Pose2& pose) {
    const double theta = 0.2 * shift_m / 5.0 * unit(rng);
    const double y = shift_m * unit(rng);
    const double x = shift_m * unit(rng);
    return Pose2(pose.x() + x, pose.y() + y, pose.theta() + theta);
  };
  double periodic_s = 0.0, final_s = 0.0;
  int64_t inserted = 0, moved = 0, final_moved = 0;
  size_t next = 0;
  for (double until = period_s; next < keyframes.size(); until += period_s) {
    const double start = CpuSeconds();
    for (; next < keyframes.size() && keyframes[next].time_s < until; ++next) {
      estimate.push_back(keyframes[next].T_world_body);
      grid.Place(next, keyframes[next].scan, estimate[next]);
      ++inserted;
    }
    // Moves drawn outside the clock would be fairer, but they cost nothing next to a trace.
    struct Move {
      double displacement;
      uint64_t key;
    };
    std::vector<Move> moves;
    for (int n = 0; n < moved_per_period && next > 0; ++n) {
      const uint64_t key = std::uniform_int_distribution<uint64_t>(0, next - 1)(rng);
      estimate[key] = shifted(estimate[key]);
      moves.push_back({grid.Displacement(key, estimate[key]).value_or(0.0), key});
    }
    std::stable_sort(moves.begin(), moves.end(),
                     [](const Move& a, const Move& b) { return a.displacement > b.displacement; });
    for (const Move& m : moves) {
      if (grid.Place(m.key, keyframes[m.key].scan, estimate[m.key]) ==
          KeyframeGrid::Placement::kMoved) {
        ++moved;
      }
    }
    (void)grid.TakeChangedTiles(0, 0);
    periodic_s += CpuSeconds() - start;
  }
  for (size_t key = 0; key < keyframes.size(); ++key) estimate[key] = shifted(estimate[key]);
  const double start = CpuSeconds();
  // As MapPublisher::UpdateGrid: made again when more keyframes moved than stayed.
  std::vector<KeyframeGrid::Keyframe> all;
  for (size_t key = 0; key < keyframes.size(); ++key) {
    const bool moves = *grid.Displacement(key, estimate[key]) > grid.move_tolerance_m();
    final_moved += moves ? 1 : 0;
    all.push_back({key, &keyframes[key].scan, moves ? estimate[key] : grid.placed().at(key)});
  }
  const bool rebuild = final_moved > static_cast<int64_t>(keyframes.size()) - final_moved;
  if (rebuild) {
    grid.Rebuild(all);
  } else {
    for (size_t key = 0; key < keyframes.size(); ++key) {
      grid.Place(key, keyframes[key].scan, estimate[key]);
    }
  }
  const std::vector<GridTile> tiles = grid.Tiles(0, 0);
  final_s = CpuSeconds() - start;
  std::printf("periodic: %.3f CPU s, %lld traced in, %lld moved (2 traces each)\n", periodic_s,
              static_cast<long long>(inserted), static_cast<long long>(moved));
  std::printf("final complete grid: %.3f CPU s, %lld moved, %s\n", final_s,
              static_cast<long long>(final_moved), rebuild ? "made again" : "moves");
  std::printf("tiles %zu hash %016llx\n", tiles.size(),
              static_cast<unsigned long long>(HashTiles(tiles)));
  return 0;
}

}  // namespace
}  // namespace anchormap

int main(int argc, char** argv) { return anchormap::Run(argc, argv); }
