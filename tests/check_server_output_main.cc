// anchormap-test-check-server-output: checks a recording of anchormap-server's outputs
// against the simulator log it was made from (used by tests/multiprocess_test.sh).
//   --map OUT.lcmlog     the server's outputs (lcm-logger recording or an offline run)
//   --truth SIM.lcmlog   the anchormap-sim log: <R>_GROUND_TRUTH and <R>_ENCOUNTER
// Checks: (1) no robot is anchored in any map before its first encounter, every robot with
// an encounter is anchored in the last map; (2) the last map's anchored keyframes, rigidly
// aligned to the truth, are within --max-rmse-m / --max-error-m; (3) anchor covariances were
// published and each anchor's trace did not grow from its first to its last publication
// (beyond --trace-tolerance). Prints the numbers; exit 0 pass, 1 fail, 2 usage.

#include <cmath>
#include <cstdio>
#include <iostream>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "common/bus/channels.h"
#include "common/bus/codec.h"
#include "common/bus/lcm_log.h"
#include "common/bus/map_codec.h"
#include "common/bus/merged_map_assembler.h"
#include "common/util/options_loader.h"

namespace anchormap {
namespace {

struct Options {
  std::string map_log;
  std::string truth_log;
  double max_rmse_m = 0.5;
  double max_error_m = 1.5;
  double trace_tolerance = 0.05;
  int min_robots = 2;
};

// Ground-truth poses of one robot in time order; linear interpolation between them.
struct TruthTrack {
  std::vector<OdometrySample> samples;
  std::optional<Pose2> At(int64_t utime) const {
    if (samples.empty() || utime < samples.front().utime || utime > samples.back().utime) {
      return std::nullopt;
    }
    size_t i = 1;
    while (i < samples.size() && samples[i].utime < utime) ++i;
    if (i >= samples.size()) return samples.back().T_odom_body;
    const OdometrySample& a = samples[i - 1];
    const OdometrySample& b = samples[i];
    if (b.utime == a.utime) return b.T_odom_body;
    const double f = static_cast<double>(utime - a.utime) / static_cast<double>(b.utime - a.utime);
    return Interpolate(a.T_odom_body, b.T_odom_body, f);
  }
};

bool EndsWith(const std::string& text, const std::string& suffix) {
  return text.size() > suffix.size() &&
         text.compare(text.size() - suffix.size(), suffix.size(), suffix) == 0;
}

int Check(const Options& options) {
  int failures = 0;
  auto fail = [&failures](const std::string& what) {
    std::printf("FAIL: %s\n", what.c_str());
    ++failures;
  };

  // --- The simulator log: ground truth and the encounters' times. ---
  std::map<std::string, TruthTrack> truth;
  std::map<std::string, int64_t> first_encounter;
  LcmLogReader sim;
  if (Status s = sim.Open(options.truth_log); !s.ok()) {
    std::fprintf(stderr, "%s\n", s.message().c_str());
    return 2;
  }
  while (auto event = sim.Next()) {
    if (EndsWith(event->channel, channels::kGroundTruthSuffix)) {
      const auto pose = DecodeOdometry(event->data.data(), event->data.size());
      if (pose.ok()) {
        truth[event->channel.substr(0, event->channel.size() - 13)].samples.push_back(*pose);
      }
    } else if (EndsWith(event->channel, channels::kEncounterSuffix)) {
      const auto e = DecodeEncounter(event->data.data(), event->data.size());
      if (!e.ok()) continue;
      for (const std::string& robot : {e->observer, e->observed}) {
        if (!first_encounter.count(robot) || e->utime < first_encounter[robot]) {
          first_encounter[robot] = e->utime;
        }
      }
    }
  }
  std::printf("truth: %zu robots, %zu with encounters\n", truth.size(), first_encounter.size());

  // --- The server's outputs. ---
  std::vector<MergedMap> maps;
  std::vector<AnchorCovariances> covariances;
  int64_t tiles = 0, undecodable = 0;
  LcmLogReader out;
  if (Status s = out.Open(options.map_log); !s.ok()) {
    std::fprintf(stderr, "%s\n", s.message().c_str());
    return 2;
  }
  MergedMapAssembler assembler;
  while (auto event = out.Next()) {
    if (assembler.IsMapChannel(event->channel)) {
      bool completed = false;
      if (!assembler.Accept(event->channel, event->data.data(), event->data.size(), &completed)
               .ok()) {
        ++undecodable;
      } else if (completed) {
        maps.push_back(*assembler.map());
      }
    } else if (event->channel == channels::kAnchorCovariances) {
      auto c = DecodeAnchorCovariances(event->data.data(), event->data.size());
      c.ok() ? covariances.push_back(*c) : void(++undecodable);
    } else if (event->channel == channels::kGridTiles) {
      ++tiles;
    }
  }
  std::printf("server output: %zu merged maps, %zu anchor covariance messages, %lld grid tiles\n",
              maps.size(), covariances.size(), static_cast<long long>(tiles));
  if (undecodable > 0) fail(std::to_string(undecodable) + " output messages do not decode");
  if (maps.empty()) {
    fail("no merged map");
    return 1;
  }

  // (1) Anchors appear only after a robot's first encounter; all robots that met are anchored.
  std::map<std::string, int64_t> first_anchored;
  for (const MergedMap& map : maps) {
    for (const MergedTrajectory& t : map.trajectories) {
      if (!t.anchored) continue;
      if (!first_anchored.count(t.robot)) first_anchored[t.robot] = map.utime;
      const auto it = first_encounter.find(t.robot);
      if (it == first_encounter.end() || map.utime < it->second) {
        fail(t.robot + " anchored in the map of " + std::to_string(map.utime) +
             " before its first encounter");
      }
    }
  }
  const MergedMap& last = maps.back();
  if (static_cast<int>(last.trajectories.size()) < options.min_robots) {
    fail("the last map has " + std::to_string(last.trajectories.size()) + " trajectories");
  }
  for (const MergedTrajectory& t : last.trajectories) {
    const bool met = first_encounter.count(t.robot) > 0;
    std::printf("  %s: %zu keyframes, %s", t.robot.c_str(), t.poses.size(),
                t.anchored ? "anchored" : "unanchored");
    if (met) {
      std::printf(", first encounter at %.2f s",
                  1e-6 * static_cast<double>(first_encounter[t.robot]));
      if (first_anchored.count(t.robot)) {
        std::printf(", first anchored map at %.2f s",
                    1e-6 * static_cast<double>(first_anchored[t.robot]));
      }
    }
    std::printf("\n");
    if (met && !t.anchored) fail(t.robot + " met another robot but is not anchored");
  }

  // (2) Anchored keyframes against the truth after a rigid 2D alignment.
  std::vector<Eigen::Vector2d> estimated, reference;
  std::vector<std::string> owner;
  for (const MergedTrajectory& t : last.trajectories) {
    if (!t.anchored || !truth.count(t.robot)) continue;
    for (size_t i = 0; i < t.poses.size() && i < t.pose_utimes.size(); ++i) {
      const auto true_pose = truth[t.robot].At(t.pose_utimes[i]);
      if (!true_pose) continue;
      estimated.push_back(t.poses[i].translation());
      reference.push_back(true_pose->translation());
      owner.push_back(t.robot);
    }
  }
  if (estimated.size() < 10) {
    fail("fewer than 10 anchored keyframes matched to the truth");
  } else {
    Eigen::Vector2d mean_e = Eigen::Vector2d::Zero(), mean_r = Eigen::Vector2d::Zero();
    for (size_t i = 0; i < estimated.size(); ++i) {
      mean_e += estimated[i];
      mean_r += reference[i];
    }
    mean_e /= static_cast<double>(estimated.size());
    mean_r /= static_cast<double>(reference.size());
    double cross = 0, dot = 0;
    for (size_t i = 0; i < estimated.size(); ++i) {
      const Eigen::Vector2d e = estimated[i] - mean_e, r = reference[i] - mean_r;
      cross += e.x() * r.y() - e.y() * r.x();
      dot += e.x() * r.x() + e.y() * r.y();
    }
    const Pose2 rotation(0, 0, std::atan2(cross, dot));
    const Eigen::Vector2d translation = mean_r - rotation.rotation() * mean_e;
    double sum_squared = 0, worst = 0;
    std::map<std::string, std::pair<double, int>> per_robot;
    for (size_t i = 0; i < estimated.size(); ++i) {
      const double error = (rotation.rotation() * estimated[i] + translation - reference[i]).norm();
      sum_squared += error * error;
      worst = std::max(worst, error);
      per_robot[owner[i]].first += error * error;
      ++per_robot[owner[i]].second;
    }
    const double rmse = std::sqrt(sum_squared / static_cast<double>(estimated.size()));
    std::printf(
        "merged map vs truth (rigid fit, %zu keyframes): RMSE %.3f m, max %.3f m (bounds %.2f, "
        "%.2f)\n",
        estimated.size(), rmse, worst, options.max_rmse_m, options.max_error_m);
    for (const auto& [robot, sums] : per_robot) {
      std::printf("  %s RMSE %.3f m\n", robot.c_str(), std::sqrt(sums.first / sums.second));
    }
    if (rmse > options.max_rmse_m) fail("RMSE above the bound");
    if (worst > options.max_error_m) fail("max error above the bound");
  }

  // (3) Anchor covariances: published; each trace shrinks (or holds) from first to last.
  if (covariances.empty()) fail("no anchor covariances published");
  std::map<std::string, std::pair<double, double>> traces;  // first, last
  for (const AnchorCovariances& c : covariances) {
    for (const AnchorCovariance& a : c.anchors) {
      const double trace = a.covariance.trace();
      if (!traces.count(a.robot)) traces[a.robot] = {trace, trace};
      traces[a.robot].second = trace;
    }
  }
  for (const auto& [robot, t] : traces) {
    std::printf("  %s anchor covariance trace: first %.5f, last %.5f\n", robot.c_str(), t.first,
                t.second);
    if (t.second > t.first * (1.0 + options.trace_tolerance) + 1e-12) {
      fail(robot + "'s anchor covariance grew");
    }
  }
  // An encounter adds information: at every published update whose map holds more
  // encounters than the previous published one, no anchor's trace may rise.
  std::map<int64_t, size_t> encounters_at;  // update -> encounters in that map
  for (const MergedMap& map : maps) encounters_at[map.update] = map.encounters.size();
  std::map<std::string, double> previous;
  size_t previous_encounters = 0;
  int checked = 0;
  for (const AnchorCovariances& c : covariances) {
    const auto it = encounters_at.find(c.update);
    const bool more = it != encounters_at.end() && it->second > previous_encounters;
    for (const AnchorCovariance& a : c.anchors) {
      const double trace = a.covariance.trace();
      if (more && previous.count(a.robot)) {
        ++checked;
        if (trace > previous[a.robot] * (1.0 + options.trace_tolerance) + 1e-12) {
          fail(a.robot + "'s anchor covariance rose at update " + std::to_string(c.update) +
               ", which added encounters");
        }
      }
      previous[a.robot] = trace;
    }
    if (it != encounters_at.end()) previous_encounters = it->second;
  }
  std::printf("  anchor traces checked at %d (anchor, update) pairs that added encounters\n",
              checked);
  std::printf(failures == 0 ? "PASS\n" : "%d check(s) failed\n", failures);
  return failures == 0 ? 0 : 1;
}

}  // namespace
}  // namespace anchormap

int main(int argc, char** argv) {
  anchormap::Options options;
  anchormap::OptionsLoader loader(
      "anchormap-test-check-server-output", "--map OUT.lcmlog --truth SIM.lcmlog",
      "Checks anchormap-server's recorded outputs against anchormap-sim's truth.");
  loader.Add("map", "map", &options.map_log, "the server's outputs (LCM log)", true);
  loader.Add("truth", "truth", &options.truth_log, "the simulator's log (LCM log)", true);
  loader.Add("max_rmse_m", "max-rmse-m", &options.max_rmse_m, "bound on the aligned RMSE (m)");
  loader.Add("max_error_m", "max-error-m", &options.max_error_m,
             "bound on the largest aligned error (m)");
  loader.Add("trace_tolerance", "trace-tolerance", &options.trace_tolerance,
             "allowed relative growth of an anchor's covariance trace (relinearisation)");
  loader.Add("min_robots", "min-robots", &options.min_robots,
             "trajectories the last map must hold");
  const anchormap::ParseOutcome outcome = loader.Parse(argc, argv);
  if (!outcome.run) return outcome.exit_code;
  return anchormap::Check(options);
}
