// anchormap-test-compare-maps: compares the last merged map of one server output log with
// another's (used by tests/loss_test.sh: the lossy online run against the lossless
// reference). Keyframes are matched by (robot, trajectory id, time), encounters by the
// keyframes they join (each named by robot, trajectory id and index); poses are compared in the
// frame of the first robot's first keyframe (the global frame is the first anchored group's, which
// depends on arrival order).
//   --map OUT.lcmlog --reference REF.lcmlog [--tolerance 1e-9] [--instances N]
// Also prints the last server_status_t of --map (bridged gaps, resend requests, refusals)
// and fails when it counts bridged gaps; with --instances N (crash_test.sh), fails unless
// --map's status messages carry N distinct server instance ids (N server processes); with
// --trajectories N (agent_restart_test.sh), fails unless --map's merged map holds N
// trajectories, every one of them anchored (joined to the others by an encounter).
// Exit 0 equal, 1 different, 2 usage.

#include <cmath>
#include <cstdio>
#include <iostream>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <tuple>

#include "common/bus/lcm_log.h"
#include "common/bus/map_codec.h"
#include "common/bus/merged_map_assembler.h"
#include "common/util/options_loader.h"

namespace anchormap {
namespace {

struct Last {
  std::optional<MergedMap> map;
  std::optional<ServerStatus> status;
  std::set<int64_t> instance_ids;
};

std::optional<Last> ReadLast(const std::string& path) {
  LcmLogReader reader;
  if (Status s = reader.Open(path); !s.ok()) {
    std::cerr << s.message() << "\n";
    return std::nullopt;
  }
  Last last;
  MergedMapAssembler assembler;
  while (auto event = reader.Next()) {
    if (assembler.IsMapChannel(event->channel)) {
      bool completed = false;
      if (assembler.Accept(event->channel, event->data.data(), event->data.size(), &completed)
              .ok() &&
          completed) {
        last.map = *assembler.map();
      }
    } else if (event->channel == "ANCHORMAP_SERVER_STATUS") {
      auto status = DecodeServerStatus(event->data.data(), event->data.size());
      if (status.ok()) {
        last.instance_ids.insert(status->instance_id);
        last.status = *status;
      }
    }
  }
  return last;
}

using TrajectoryKey = std::pair<std::string, int64_t>;
// (robot, trajectory) -> utime -> pose, and the count of each utime (doubles).
struct Index {
  std::map<TrajectoryKey, std::map<int64_t, Pose2>> poses;
  int64_t keyframes = 0, doubled = 0;
  std::set<std::tuple<std::string, int64_t, std::string, int64_t>> links;
  int64_t link_count = 0;
};

Index Build(const MergedMap& map) {
  Index index;
  std::map<TrajectoryKey, const MergedTrajectory*> by_id;
  for (const MergedTrajectory& t : map.trajectories) {
    by_id[{t.robot, t.trajectory_id}] = &t;
    auto& poses = index.poses[{t.robot, t.trajectory_id}];
    for (size_t i = 0; i < t.poses.size(); ++i) {
      ++index.keyframes;
      if (!poses.emplace(t.pose_utimes[i], t.poses[i]).second) ++index.doubled;
    }
  }
  auto keyframe = [&](const std::string& robot, int64_t trajectory,
                      int32_t i) -> std::pair<std::string, int64_t> {
    const TrajectoryKey key{robot, trajectory};
    const MergedTrajectory* t = by_id.count(key) ? by_id[key] : nullptr;
    if (!t || i < 0 || static_cast<size_t>(i) >= t->pose_utimes.size()) return {"?", -1};
    return {t->robot, t->pose_utimes[static_cast<size_t>(i)]};
  };
  for (const EncounterLink& l : map.encounters) {
    const auto a = keyframe(l.robot_a, l.trajectory_a, l.index_a);
    const auto b = keyframe(l.robot_b, l.trajectory_b, l.index_b);
    ++index.link_count;
    index.links.insert({a.first, a.second, b.first, b.second});
  }
  return index;
}

int Main(int argc, char** argv) {
  std::string map_path, reference_path;
  double tolerance = 1e-9;
  int instances = 0;
  int trajectories = 0;
  OptionsLoader loader("anchormap-test-compare-maps", "--map OUT.lcmlog --reference REF.lcmlog",
                       "Compares the last merged maps of two server output logs.");
  loader.Add("map", "map", &map_path, "server outputs to check", true);
  loader.Add("reference", "reference", &reference_path, "server outputs to compare with", true);
  loader.Add("tolerance", "tolerance", &tolerance, "pose tolerance (m, rad)");
  loader.Add("instances", "instances", &instances,
             "server instance ids expected in --map's status messages (0 = not checked)");
  loader.Add("trajectories", "trajectories", &trajectories,
             "trajectories expected in --map's merged map, all anchored (0 = not checked)");
  const ParseOutcome outcome = loader.Parse(argc, argv);
  if (!outcome.run) return outcome.exit_code;
  const auto got = ReadLast(map_path);
  const auto want = ReadLast(reference_path);
  if (!got || !want) return 2;
  if (!got->map || !want->map) {
    std::cout << "compare-maps: no merged map in " << (got->map ? reference_path : map_path)
              << "\n";
    return 1;
  }
  bool ok = true;
  if (want->status && want->status->bridged_gaps > 0) {
    std::cout << "compare-maps: the reference bridged " << want->status->bridged_gaps
              << " gaps: it is incomplete (its recording lost datagrams)\n";
    ok = false;
  }
  if (got->status) {
    const ServerStatus& s = *got->status;
    std::cout << "compare-maps: server status: keyframes " << s.keyframes << " encounters "
              << s.encounters << " bridged gaps " << s.bridged_gaps << " resend requests "
              << s.resend_requests << " kernel drops " << s.kernel_drops << " refused:";
    for (const auto& [reason, count] : s.rejections) std::cout << " " << reason << "=" << count;
    std::cout << "\n";
    if (s.bridged_gaps != 0) ok = false;
  }
  std::cout << "compare-maps: " << got->instance_ids.size() << " server instance id(s) in "
            << map_path << "\n";
  if (instances > 0 && static_cast<int>(got->instance_ids.size()) != instances) {
    std::cout << "compare-maps: expected " << instances << " server instances\n";
    ok = false;
  }
  if (trajectories > 0) {
    int anchored = 0;
    for (const MergedTrajectory& t : got->map->trajectories) {
      anchored += t.anchored ? 1 : 0;
      std::cout << "compare-maps: trajectory " << t.robot << " " << t.trajectory_id << ": "
                << t.poses.size() << " keyframes, " << (t.anchored ? "anchored" : "NOT anchored")
                << "\n";
    }
    if (static_cast<int>(got->map->trajectories.size()) != trajectories ||
        anchored != trajectories) {
      std::cout << "compare-maps: expected " << trajectories << " trajectories, all anchored\n";
      ok = false;
    }
  }
  const Index g = Build(*got->map);
  const Index w = Build(*want->map);
  int64_t missing = 0, extra = 0;
  double worst = 0.0;
  // Frame of comparison: the first keyframe of the first trajectory of the reference.
  const auto& [origin_key, origin_poses] = *w.poses.begin();
  std::optional<Pose2> got_origin, want_origin = origin_poses.begin()->second;
  if (g.poses.count(origin_key) && g.poses.at(origin_key).count(origin_poses.begin()->first)) {
    got_origin = g.poses.at(origin_key).at(origin_poses.begin()->first);
  }
  for (const auto& [key, poses] : w.poses) {
    const auto it = g.poses.find(key);
    for (const auto& [utime, pose] : poses) {
      if (it == g.poses.end() || !it->second.count(utime)) {
        ++missing;
        continue;
      }
      if (!got_origin) continue;
      const Pose2 a = Between(*want_origin, pose);
      const Pose2 b = Between(*got_origin, it->second.at(utime));
      worst = std::max({worst, std::abs(a.x() - b.x()), std::abs(a.y() - b.y()),
                        std::abs(AngleDifference(a.theta(), b.theta()))});
    }
  }
  for (const auto& [key, poses] : g.poses) {
    const auto it = w.poses.find(key);
    for (const auto& [utime, pose] : poses) {
      if (it == w.poses.end() || !it->second.count(utime)) ++extra;
    }
  }
  int64_t links_missing = 0, links_extra = 0;
  for (const auto& l : w.links) links_missing += g.links.count(l) ? 0 : 1;
  for (const auto& l : g.links) links_extra += w.links.count(l) ? 0 : 1;
  std::printf(
      "compare-maps: keyframes %lld (reference %lld): missing %lld, extra %lld, doubled %lld; "
      "encounters %lld (reference %lld): missing %lld, extra %lld, doubled %lld; "
      "largest pose difference %.3g (tolerance %.3g)\n",
      static_cast<long long>(g.keyframes), static_cast<long long>(w.keyframes),
      static_cast<long long>(missing), static_cast<long long>(extra),
      static_cast<long long>(g.doubled), static_cast<long long>(g.link_count),
      static_cast<long long>(w.link_count), static_cast<long long>(links_missing),
      static_cast<long long>(links_extra),
      static_cast<long long>(g.link_count - static_cast<int64_t>(g.links.size())), worst,
      tolerance);
  ok = ok && got_origin && missing == 0 && extra == 0 && g.doubled == 0 && links_missing == 0 &&
       links_extra == 0 && g.link_count == static_cast<int64_t>(g.links.size()) &&
       g.link_count == w.link_count && worst <= tolerance;
  std::cout << (ok ? "compare-maps: equal\n" : "compare-maps: DIFFERENT\n");
  return ok ? 0 : 1;
}

}  // namespace
}  // namespace anchormap

int main(int argc, char** argv) { return anchormap::Main(argc, argv); }
