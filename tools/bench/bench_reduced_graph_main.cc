// anchormap-bench-reduced-graph [--map OUT.lcmlog] [--truth SIM.lcmlog] [--world-robots N
//     --world-seed S] [--rules 0.5:20,1:30] [--slice-s 150]
//
// How many pose variables a reduced pose graph (tools/bench/area_node_selector.h) would keep
// for a team's keyframes, per slice of data time, against the keyframes the server holds
// now. Keyframes come from a server output (--map: the last complete merged map of
// `anchormap-replay --output`: each trajectory's keyframe times and global poses, the
// encounter links) or, without --map, from the simulator's truth (--truth: the agents'
// Keyframer rule applied to <ROBOT>_GROUND_TRUTH). Each keyframe, in time order, folds onto
// an existing node within a rule's radius and angle or becomes a node. The poses compared
// are the map's final estimates ("estimate") and/or the truth at the keyframe's time
// ("truth"). Three scopes: "own" (only its trajectory's nodes), "group" (nodes of the
// trajectories joined to it by the encounter links accepted so far, the link's time being its
// later keyframe's) and "all" (every node: an upper bound). With --world-robots (and the
// sim's --seed) the office world is rebuilt and a fold also needs a line of sight between the
// true positions (a proxy of the scan overlap the server would check by matching). For the
// estimate, folds whose true positions lie more than twice the radius apart count as wrong.
// Prints one table per source and scope: per slice, the keyframes so far, the full graph's
// factors so far (odometry and links), and per rule the nodes so far (+ those added in the
// slice) and the distinct node pairs joined by a factor (in brackets: by odometry alone).
//
// --solve full|reduced (with --map and --truth; the first --rules entry, --until-s): instead,
// replays the graph into the server's smoother (tools/bench/area_graph_replay.h: a pose per
// keyframe, or per node of the rule with the group scope and no world; synthetic
// measurements from the truth) and prints per slice the updates' CPU (sum, p99, max) and
// the smoother's variables, factors and nnz(R), then the keyframes' position RMSE against the
// truth after the last update and after a final batch step.
// Single-threaded; reading a 20 x 1800 map output (4 GB) takes about two minutes.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <map>
#include <memory>
#include <numeric>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <boost/program_options.hpp>

#include "agent/keyframer.h"
#include "common/bus/channels.h"
#include "common/bus/lcm_log.h"
#include "common/bus/merged_map_assembler.h"
#include "tools/bench/area_graph_replay.h"
#include "tools/bench/area_node_selector.h"
#include "tools/eval/eval_inputs.h"
#include "tools/sim/sim_options.h"
#include "tools/sim/simulator.h"

namespace anchormap {
namespace {

struct Keyframe {
  int64_t utime = 0;
  int trajectory = 0;
  int index = 0;          // in its trajectory
  bool anchored = false;  // the estimate is global (else in its trajectory's local frame)
  bool has_estimate = false;
  bool has_truth = false;
  Pose2 estimate;
  Pose2 truth;
};

struct Link {         // an encounter or loop closure between keyframes a and b (sorted positions)
  int64_t utime = 0;  // its later keyframe's
  int trajectory_a = 0;
  int index_a = 0;
  int trajectory_b = 0;
  int index_b = 0;
  int a = 0;
  int b = 0;
};

struct Inputs {
  std::vector<std::string> trajectory_names;
  std::vector<Keyframe> keyframes;  // sorted by time
  std::vector<Link> links;          // sorted by time
  int64_t links_between_trajectories = 0;
  double max_truth_gap_s = 0.0;  // largest |keyframe time - nearest truth time|
};

Status ReadMap(const std::string& path, MergedMap* map) {
  LcmLogReader reader;
  if (Status s = reader.Open(path); !s.ok()) return s;
  MergedMapAssembler assembler;
  while (auto event = reader.Next()) {
    if (!assembler.IsMapChannel(event->channel)) continue;
    (void)assembler.Accept(event->channel, event->data.data(), event->data.size());
  }
  if (!assembler.map()) return Status::Error(path + ": no complete merged map");
  *map = *assembler.map();
  return Status::Ok();
}

// The truth sample nearest in time; false when `poses` is empty.
bool NearestTruth(const StampedTrajectory& poses, int64_t utime, Pose2* pose, double* gap_s) {
  if (poses.empty()) return false;
  auto it = std::lower_bound(poses.begin(), poses.end(), utime,
                             [](const StampedPose2& p, int64_t t) { return p.utime < t; });
  if (it == poses.end() || (it != poses.begin() && utime - (it - 1)->utime < it->utime - utime)) {
    --it;
  }
  *pose = it->pose;
  *gap_s = 1e-6 * static_cast<double>(std::llabs(it->utime - utime));
  return true;
}

Status LoadInputs(const std::string& map_path, const std::string& truth_path, Inputs* inputs) {
  ReferenceSet truth;
  if (!truth_path.empty()) {
    if (Status s = ReadReferences(truth_path, "", &truth); !s.ok()) return s;
  }
  if (!map_path.empty()) {
    MergedMap map;
    if (Status s = ReadMap(map_path, &map); !s.ok()) return s;
    std::map<std::pair<std::string, int64_t>, int> number;
    for (const MergedTrajectory& t : map.trajectories) {
      const int n = static_cast<int>(inputs->trajectory_names.size());
      number[{t.robot, t.trajectory_id}] = n;
      inputs->trajectory_names.push_back(t.robot + "/" + std::to_string(t.trajectory_id));
      const auto found = truth.by_robot.find(t.robot);
      for (size_t i = 0; i < t.poses.size() && i < t.pose_utimes.size(); ++i) {
        Keyframe k;
        k.utime = t.pose_utimes[i];
        k.trajectory = n;
        k.index = static_cast<int>(i);
        k.anchored = t.anchored;
        k.has_estimate = true;
        k.estimate = t.poses[i];
        double gap_s = 0.0;
        if (found != truth.by_robot.end() &&
            NearestTruth(found->second, k.utime, &k.truth, &gap_s)) {
          k.has_truth = true;
          inputs->max_truth_gap_s = std::max(inputs->max_truth_gap_s, gap_s);
        }
        inputs->keyframes.push_back(k);
      }
    }
    for (const EncounterLink& link : map.encounters) {
      const auto a = number.find({link.robot_a, link.trajectory_a});
      const auto b = number.find({link.robot_b, link.trajectory_b});
      if (a == number.end() || b == number.end()) continue;
      const MergedTrajectory& ta = map.trajectories[static_cast<size_t>(a->second)];
      const MergedTrajectory& tb = map.trajectories[static_cast<size_t>(b->second)];
      if ((a->second != b->second && (!ta.anchored || !tb.anchored)) || link.index_a < 0 ||
          link.index_b < 0 || static_cast<size_t>(link.index_a) >= ta.pose_utimes.size() ||
          static_cast<size_t>(link.index_b) >= tb.pose_utimes.size()) {
        continue;
      }
      Link l;
      l.utime = std::max(ta.pose_utimes[static_cast<size_t>(link.index_a)],
                         tb.pose_utimes[static_cast<size_t>(link.index_b)]);
      l.trajectory_a = a->second;
      l.index_a = link.index_a;
      l.trajectory_b = b->second;
      l.index_b = link.index_b;
      inputs->links.push_back(l);
      if (a->second != b->second) ++inputs->links_between_trajectories;
    }
  } else {
    // The agents' keyframe rule on the truth (the agents apply it to odometry).
    for (const auto& [robot, poses] : truth.by_robot) {
      const int n = static_cast<int>(inputs->trajectory_names.size());
      inputs->trajectory_names.push_back(robot);
      Keyframer keyframer;
      for (const StampedPose2& p : poses) {
        if (!keyframer.ShouldMake(p.pose, p.utime)) continue;
        keyframer.Accept(p.pose, p.utime);
        Keyframe k;
        k.utime = p.utime;
        k.trajectory = n;
        k.index = static_cast<int>(inputs->keyframes.size());  // unique; no links here
        k.has_truth = true;
        k.truth = p.pose;
        inputs->keyframes.push_back(k);
      }
    }
  }
  std::stable_sort(inputs->keyframes.begin(), inputs->keyframes.end(),
                   [](const Keyframe& a, const Keyframe& b) { return a.utime < b.utime; });
  std::stable_sort(inputs->links.begin(), inputs->links.end(),
                   [](const Link& a, const Link& b) { return a.utime < b.utime; });
  std::map<std::pair<int, int>, int> position;  // (trajectory, index) -> sorted position
  for (size_t i = 0; i < inputs->keyframes.size(); ++i) {
    position[{inputs->keyframes[i].trajectory, inputs->keyframes[i].index}] = static_cast<int>(i);
  }
  for (Link& l : inputs->links) {
    l.a = position.at({l.trajectory_a, l.index_a});
    l.b = position.at({l.trajectory_b, l.index_b});
  }
  return inputs->keyframes.empty() ? Status::Error("no keyframes") : Status::Ok();
}

enum class Scope { kOwn, kGroup, kAll };
const char* ScopeName(Scope s) {
  return s == Scope::kOwn ? "own" : s == Scope::kGroup ? "group" : "all";
}

struct RunResult {
  std::vector<int> nodes_by_slice;  // cumulative
  // Distinct pairs of nodes joined by a factor (odometry between a trajectory's successive
  // keyframes' nodes, the links), cumulative: R's structure when the factors between the
  // same two nodes are combined into one.
  std::vector<int64_t> pairs_by_slice;
  std::vector<int64_t> odometry_pairs_by_slice;  // those of odometry factors alone
  int64_t folds = 0;
  int64_t wrong_folds = 0;  // estimate only, with truth: true positions > 2 radius apart
  double max_fold_truth_distance_m = 0.0;
};

int FindRoot(std::vector<int>* parent, int i) {
  while ((*parent)[static_cast<size_t>(i)] != i) {
    i = (*parent)[static_cast<size_t>(i)] =
        (*parent)[static_cast<size_t>((*parent)[static_cast<size_t>(i)])];
  }
  return i;
}

RunResult Run(const Inputs& inputs, bool use_truth, Scope scope, const AreaNodeRule& rule,
              const sim::World* world, int64_t start_utime, int64_t slice_utime, int slices) {
  RunResult result;
  result.nodes_by_slice.assign(static_cast<size_t>(slices), 0);
  result.pairs_by_slice.assign(static_cast<size_t>(slices), 0);
  result.odometry_pairs_by_slice.assign(static_cast<size_t>(slices), 0);
  std::vector<int> node_of(inputs.keyframes.size(), -1);
  std::vector<int> last_node(inputs.trajectory_names.size(), -1);
  std::set<std::pair<int, int>> pairs, odometry_pairs;
  const auto join = [](int a, int b, std::set<std::pair<int, int>>* to) {
    if (a != b) to->insert({std::min(a, b), std::max(a, b)});
  };
  AreaNodeSelector selector(rule);
  std::vector<int> parent(inputs.trajectory_names.size());
  std::iota(parent.begin(), parent.end(), 0);
  size_t next_link = 0;
  const std::vector<Keyframe>& keyframes = inputs.keyframes;
  for (size_t i = 0; i < keyframes.size(); ++i) {
    const Keyframe& k = keyframes[i];
    // The links whose keyframes are all in (a link's time is its later keyframe's).
    for (; next_link < inputs.links.size() && inputs.links[next_link].utime < k.utime;
         ++next_link) {
      const Link& l = inputs.links[next_link];
      parent[static_cast<size_t>(FindRoot(&parent, l.trajectory_a))] =
          FindRoot(&parent, l.trajectory_b);
      join(node_of[static_cast<size_t>(l.a)], node_of[static_cast<size_t>(l.b)], &pairs);
    }
    const Pose2& pose = use_truth ? k.truth : k.estimate;
    // An estimate in a local frame (never anchored) shares it with its own trajectory only.
    const bool own_frame_only = scope == Scope::kOwn || (!use_truth && !k.anchored);
    const AreaNodeSelector::Eligible eligible = [&](const AreaNodeSelector::Node& node) {
      const Keyframe& n = keyframes[static_cast<size_t>(node.keyframe)];
      if (own_frame_only && n.trajectory != k.trajectory) return false;
      if (scope == Scope::kGroup &&
          FindRoot(&parent, n.trajectory) != FindRoot(&parent, k.trajectory)) {
        return false;
      }
      if (!use_truth && !n.anchored && n.trajectory != k.trajectory) return false;
      if (world != nullptr && k.has_truth && n.has_truth &&
          !world->LineOfSight(k.truth.translation(), n.truth.translation())) {
        return false;
      }
      return true;
    };
    const int folded = selector.Add(static_cast<int>(i), pose, eligible);
    node_of[i] = folded >= 0 ? folded : selector.num_nodes() - 1;
    int& last = last_node[static_cast<size_t>(k.trajectory)];
    if (last >= 0) {
      join(last, node_of[i], &pairs);
      join(last, node_of[i], &odometry_pairs);
    }
    last = node_of[i];
    if (folded >= 0) {
      ++result.folds;
      const Keyframe& n = keyframes[static_cast<size_t>(selector.node(folded).keyframe)];
      if (!use_truth && k.has_truth && n.has_truth) {
        const double d = (k.truth.translation() - n.truth.translation()).norm();
        result.max_fold_truth_distance_m = std::max(result.max_fold_truth_distance_m, d);
        if (d > 2.0 * rule.radius_m) ++result.wrong_folds;
      }
    }
    const int64_t slice = std::min<int64_t>((k.utime - start_utime) / slice_utime, slices - 1);
    result.nodes_by_slice[static_cast<size_t>(slice)] = selector.num_nodes();
    result.pairs_by_slice[static_cast<size_t>(slice)] = static_cast<int64_t>(pairs.size());
    result.odometry_pairs_by_slice[static_cast<size_t>(slice)] =
        static_cast<int64_t>(odometry_pairs.size());
  }
  for (; next_link < inputs.links.size(); ++next_link) {
    join(node_of[static_cast<size_t>(inputs.links[next_link].a)],
         node_of[static_cast<size_t>(inputs.links[next_link].b)], &pairs);
  }
  result.pairs_by_slice[static_cast<size_t>(slices - 1)] = static_cast<int64_t>(pairs.size());
  for (int s = 1; s < slices; ++s) {  // slices without keyframes keep the count before them
    result.nodes_by_slice[static_cast<size_t>(s)] =
        std::max(result.nodes_by_slice[static_cast<size_t>(s)],
                 result.nodes_by_slice[static_cast<size_t>(s - 1)]);
    result.pairs_by_slice[static_cast<size_t>(s)] =
        std::max(result.pairs_by_slice[static_cast<size_t>(s)],
                 result.pairs_by_slice[static_cast<size_t>(s - 1)]);
    result.odometry_pairs_by_slice[static_cast<size_t>(s)] =
        std::max(result.odometry_pairs_by_slice[static_cast<size_t>(s)],
                 result.odometry_pairs_by_slice[static_cast<size_t>(s - 1)]);
  }
  return result;
}

// --solve: the full or reduced graph through the smoother (area_graph_replay.h); prints per
// slice the updates' CPU (sum, p99, max) and the smoother's variables, factors and nnz(R).
int Solve(const std::string& map_path, const std::string& truth_path, const std::string& solve,
          const std::string& rules_text, double slice_s, double until_s) {
  AreaReplayOptions options;
  options.reduced = solve == "reduced";
  options.until_s = until_s;
  double radius_m = 0.0, angle_deg = 0.0;
  if ((solve != "full" && !options.reduced) || map_path.empty() || truth_path.empty() ||
      std::sscanf(rules_text.c_str(), "%lf:%lf", &radius_m, &angle_deg) != 2 || !(radius_m > 0) ||
      !(angle_deg > 0)) {
    std::fprintf(stderr, "--solve full|reduced needs --map, --truth and a rule\n");
    return 1;
  }
  options.rule = {radius_m, angle_deg * M_PI / 180.0};
  Inputs inputs;
  if (Status s = LoadInputs(map_path, truth_path, &inputs); !s.ok()) {
    std::fprintf(stderr, "%s\n", s.message().c_str());
    return 1;
  }
  std::vector<AreaReplayKeyframe> keyframes;
  for (const Keyframe& k : inputs.keyframes) {
    if (!k.has_truth) {
      std::fprintf(stderr, "a keyframe without truth\n");
      return 1;
    }
    keyframes.push_back({k.utime, k.trajectory, k.truth});
  }
  std::vector<AreaReplayLink> links;
  for (const Link& l : inputs.links) links.push_back({l.utime, l.a, l.b});
  std::vector<AreaReplayUpdate> updates;
  AreaReplayAccuracy accuracy;
  if (Status s = ReplayAreaGraph(keyframes, links, static_cast<int>(inputs.trajectory_names.size()),
                                 options, &updates, &accuracy);
      !s.ok()) {
    std::fprintf(stderr, "replay: %s\n", s.message().c_str());
    return 1;
  }
  std::printf("%s graph (%s), %zu updates\n%8s %8s %10s %10s %10s %8s %10s %10s %10s %10s\n",
              solve.c_str(), rules_text.c_str(), updates.size(), "end_s", "updates", "cpu_s",
              "p99_ms", "max_ms", "batches", "batch_s", "variables", "factors", "nnz_r");
  for (size_t begin = 0; begin < updates.size();) {
    const int slice = static_cast<int>(updates[begin].data_s / slice_s - 1e-9);
    size_t end = begin;
    std::vector<double> cpu;
    int batches = 0;
    double batch_s = 0.0;
    while (end < updates.size() &&
           static_cast<int>(updates[end].data_s / slice_s - 1e-9) == slice) {
      if (updates[end].batch_step) {
        ++batches;
        batch_s += updates[end].cpu_s;
      }
      cpu.push_back(updates[end++].cpu_s);
    }
    std::sort(cpu.begin(), cpu.end());
    const double sum = std::accumulate(cpu.begin(), cpu.end(), 0.0);
    const size_t p99 = std::min(cpu.size() - 1, static_cast<size_t>(0.99 * cpu.size()));
    const AreaReplayUpdate& last = updates[end - 1];
    std::printf("%8.0f %8zu %10.2f %10.1f %10.1f %8d %10.2f %10lld %10lld %10lld\n",
                (slice + 1) * slice_s, cpu.size(), sum, 1e3 * cpu[p99], 1e3 * cpu.back(), batches,
                batch_s, static_cast<long long>(last.variables),
                static_cast<long long>(last.factors), static_cast<long long>(last.nnz_r));
    begin = end;
  }
  std::printf(
      "keyframe position RMSE against the truth: %.4f m after the last update, %.4f m after "
      "a final batch step\n",
      accuracy.after_updates_m, accuracy.after_batch_m);
  return 0;
}

int Main(int argc, char** argv) {
  namespace po = boost::program_options;
  std::string map_path, truth_path, rules_text = "0.5:20,1:30";
  double slice_s = 150.0;
  int world_robots = 0;
  uint64_t world_seed = 1;
  std::string solve;
  double until_s = 1e18;
  po::options_description desc("anchormap-bench-reduced-graph");
  desc.add_options()("help", "this help")("map", po::value(&map_path),
                                          "a server output (anchormap-replay --output)")(
      "truth", po::value(&truth_path), "the simulation log (<ROBOT>_GROUND_TRUTH)")(
      "world-robots", po::value(&world_robots)->default_value(0),
      "rebuild the office world of a simulation of this many robots (0: no line-of-sight check)")(
      "world-seed", po::value(&world_seed)->default_value(world_seed), "that simulation's seed")(
      "rules", po::value(&rules_text)->default_value(rules_text),
      "radius_m:angle_deg, comma separated")("slice-s", po::value(&slice_s)->default_value(slice_s),
                                             "seconds of data time per slice")(
      "solve", po::value(&solve),
      "full|reduced: replay the graph into the server's smoother instead (--map and --truth; "
      "the first rule)")("until-s", po::value(&until_s)->default_value(until_s),
                         "with --solve: data seconds to replay");
  po::variables_map vm;
  po::store(po::parse_command_line(argc, argv, desc), vm);
  po::notify(vm);
  if (vm.count("help") || (map_path.empty() && truth_path.empty()) || !(slice_s > 0)) {
    std::printf("%s", "see the comment at the top of bench_reduced_graph_main.cc\n");
    return vm.count("help") ? 0 : 1;
  }
  if (!solve.empty()) return Solve(map_path, truth_path, solve, rules_text, slice_s, until_s);
  std::vector<AreaNodeRule> rules;
  std::stringstream rules_stream(rules_text);
  for (std::string item; std::getline(rules_stream, item, ',');) {
    double radius_m = 0.0, angle_deg = 0.0;
    if (std::sscanf(item.c_str(), "%lf:%lf", &radius_m, &angle_deg) != 2 || !(radius_m > 0) ||
        !(angle_deg > 0)) {
      std::fprintf(stderr, "bad rule '%s' (radius_m:angle_deg)\n", item.c_str());
      return 1;
    }
    rules.push_back({radius_m, angle_deg * M_PI / 180.0});
  }
  std::unique_ptr<sim::Simulator> simulator;
  if (world_robots > 0) {
    sim::SimOptions options;
    options.robots = world_robots;
    options.seed = world_seed;
    if (Status s = sim::Simulator::Create(options, &simulator); !s.ok()) {
      std::fprintf(stderr, "%s\n", s.message().c_str());
      return 1;
    }
  }
  Inputs inputs;
  if (Status s = LoadInputs(map_path, truth_path, &inputs); !s.ok()) {
    std::fprintf(stderr, "%s\n", s.message().c_str());
    return 1;
  }
  const int64_t start_utime = inputs.keyframes.front().utime;
  const int64_t slice_utime = static_cast<int64_t>(slice_s * 1e6);
  const int slices =
      static_cast<int>((inputs.keyframes.back().utime - start_utime) / slice_utime) + 1;
  std::vector<int> keyframes_by_slice(static_cast<size_t>(slices), 0);
  for (const Keyframe& k : inputs.keyframes) {
    ++keyframes_by_slice[static_cast<size_t>((k.utime - start_utime) / slice_utime)];
  }
  std::partial_sum(keyframes_by_slice.begin(), keyframes_by_slice.end(),
                   keyframes_by_slice.begin());
  // The full graph's factors so far: odometry between successive keyframes, the links.
  std::vector<int64_t> factors_by_slice(static_cast<size_t>(slices), 0);
  std::vector<bool> started(inputs.trajectory_names.size(), false);
  for (const Keyframe& k : inputs.keyframes) {
    if (started[static_cast<size_t>(k.trajectory)]) {
      ++factors_by_slice[static_cast<size_t>((k.utime - start_utime) / slice_utime)];
    }
    started[static_cast<size_t>(k.trajectory)] = true;
  }
  for (const Link& l : inputs.links) {
    ++factors_by_slice[static_cast<size_t>((l.utime - start_utime) / slice_utime)];
  }
  std::partial_sum(factors_by_slice.begin(), factors_by_slice.end(), factors_by_slice.begin());
  std::printf(
      "%zu trajectories, %zu keyframes, %zu links (%lld between trajectories), %d slices of "
      "%.0f s%s",
      inputs.trajectory_names.size(), inputs.keyframes.size(), inputs.links.size(),
      static_cast<long long>(inputs.links_between_trajectories), slices, slice_s,
      world_robots > 0 ? ", line of sight in the office world" : "");
  if (!map_path.empty() && !truth_path.empty()) {
    std::printf(", truth at most %.3f s from a keyframe", inputs.max_truth_gap_s);
  }
  std::printf("\n");
  const sim::World* world = simulator ? &simulator->world() : nullptr;
  for (const bool use_truth : {false, true}) {
    if (use_truth ? truth_path.empty() : map_path.empty()) continue;
    for (const Scope scope : {Scope::kOwn, Scope::kGroup, Scope::kAll}) {
      if (scope == Scope::kGroup && inputs.links.empty()) continue;
      std::vector<RunResult> results;
      for (const AreaNodeRule& rule : rules) {
        results.push_back(
            Run(inputs, use_truth, scope, rule, world, start_utime, slice_utime, slices));
      }
      std::printf(
          "\nsource %s, scope %s: nodes so far (+ added in the slice), node pairs with a factor "
          "(with an odometry factor)\n"
          "%8s %10s %10s",
          use_truth ? "truth" : "estimate", ScopeName(scope), "end_s", "keyframes", "factors");
      for (const AreaNodeRule& rule : rules) {
        char name[64];
        std::snprintf(name, sizeof(name), "%gm/%gdeg", rule.radius_m,
                      rule.angle_rad * 180.0 / M_PI);
        std::printf(" %32s", name);
      }
      std::printf("\n");
      for (int s = 0; s < slices; ++s) {
        std::printf("%8.0f %10d %10lld", (s + 1) * slice_s,
                    keyframes_by_slice[static_cast<size_t>(s)],
                    static_cast<long long>(factors_by_slice[static_cast<size_t>(s)]));
        for (const RunResult& r : results) {
          const int now = r.nodes_by_slice[static_cast<size_t>(s)];
          const int before = s > 0 ? r.nodes_by_slice[static_cast<size_t>(s - 1)] : 0;
          char cell[64];
          std::snprintf(cell, sizeof(cell), "%d (+%d) %lld (%lld)", now, now - before,
                        static_cast<long long>(r.pairs_by_slice[static_cast<size_t>(s)]),
                        static_cast<long long>(r.odometry_pairs_by_slice[static_cast<size_t>(s)]));
          std::printf(" %32s", cell);
        }
        std::printf("\n");
      }
      if (!use_truth && !truth_path.empty()) {
        std::printf("%30s", "wrong folds");
        for (const RunResult& r : results) {
          char cell[64];
          std::snprintf(cell, sizeof(cell), "%lld/%lld max %.1fm",
                        static_cast<long long>(r.wrong_folds), static_cast<long long>(r.folds),
                        r.max_fold_truth_distance_m);
          std::printf(" %32s", cell);
        }
        std::printf("\n");
      }
    }
  }
  return 0;
}

}  // namespace
}  // namespace anchormap

int main(int argc, char** argv) { return anchormap::Main(argc, argv); }
