#include "tools/bench/area_graph_replay.h"

#include <time.h>

#include <cmath>
#include <numeric>
#include <random>

#include "common/solver/smoother.h"
#include "common/solver/smoother_options.h"

namespace anchormap {
namespace {

double ThreadCpuSeconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

// Noise levels of the synthetic measurements (sigma x, y in metres, theta in radians).
const Eigen::Vector3d kOdometrySigma(0.02, 0.02, 0.005);
const Eigen::Vector3d kMatchSigma(0.01, 0.01, 0.002);
const Eigen::Vector3d kLinkSigma(0.03, 0.03, 0.005);

Eigen::Matrix3d Covariance(const Eigen::Vector3d& sigma) {
  return sigma.cwiseProduct(sigma).asDiagonal();
}

class Noisy {
 public:
  explicit Noisy(uint64_t seed) : engine_(seed) {}
  Pose2 operator()(const Pose2& pose, const Eigen::Vector3d& sigma) {
    return Pose2(pose.x() + sigma.x() * normal_(engine_), pose.y() + sigma.y() * normal_(engine_),
                 pose.theta() + sigma.z() * normal_(engine_));
  }

 private:
  std::mt19937_64 engine_;
  std::normal_distribution<double> normal_;
};

int FindRoot(std::vector<int>* parent, int i) {
  while ((*parent)[static_cast<size_t>(i)] != i) {
    i = (*parent)[static_cast<size_t>(i)] =
        (*parent)[static_cast<size_t>((*parent)[static_cast<size_t>(i)])];
  }
  return i;
}

// Where a keyframe is in the graph: its pose variable, or a node's plus a matched offset.
struct Placement {
  PoseKey node;
  Pose2 T_node_keyframe;
  bool folded = false;
};

}  // namespace

Status ReplayAreaGraph(const std::vector<AreaReplayKeyframe>& keyframes,
                       const std::vector<AreaReplayLink>& links, int trajectories,
                       const AreaReplayOptions& options, std::vector<AreaReplayUpdate>* updates,
                       AreaReplayAccuracy* accuracy) {
  updates->clear();
  if (keyframes.empty()) return Status::Ok();
  Smoother smoother(ServerModeWithCorrectionOptions());
  // Separate streams, so that both graphs see the same draws for the same measurement.
  Noisy odometry_noise(options.seed), match_noise(options.seed + 1), link_noise(options.seed + 2);
  AreaNodeSelector selector(options.rule);
  std::vector<PoseKey> node_keys;  // by selector node
  std::vector<int32_t> poses(static_cast<size_t>(trajectories), 0);
  std::vector<int> last(static_cast<size_t>(trajectories), -1);  // last keyframe position
  std::vector<Placement> placement(keyframes.size());
  std::vector<int> parent(static_cast<size_t>(trajectories));
  std::iota(parent.begin(), parent.end(), 0);
  const int64_t start = keyframes.front().utime;
  const int64_t period = static_cast<int64_t>(options.period_s * 1e6);
  int64_t next_update = start + period;
  size_t next_link = 0;

  // A factor between the places of two keyframes, measured as `T_a_b` between the
  // keyframes themselves: composed with their offsets, each match counted twice (an offset
  // is shared by the factors on either side of it).
  const auto add_factor = [&](const Placement& a, const Placement& b, const Pose2& T_a_b,
                              Eigen::Matrix3d covariance) -> Status {
    if (a.node == b.node) return Status::Ok();
    if (a.folded) covariance += 2.0 * Covariance(kMatchSigma);
    if (b.folded) covariance += 2.0 * Covariance(kMatchSigma);
    const Pose2 z = Compose(Compose(a.T_node_keyframe, T_a_b), b.T_node_keyframe.Inverse());
    return a.node.trajectory == b.node.trajectory
               ? smoother.AddBetween(a.node, b.node, z, covariance)
               : smoother.AddEncounter(a.node, b.node, z, covariance);
  };
  const auto update = [&](int64_t utime) -> Status {
    const double before = ThreadCpuSeconds();
    const UpdateResult result = smoother.Update();
    const double cpu_s = ThreadCpuSeconds() - before;
    if (!result.status.ok()) return result.status;
    const SmootherStats& stats = smoother.stats();
    updates->push_back({1e-6 * static_cast<double>(utime - start), cpu_s, stats.variables,
                        stats.factors, stats.nnz_r, result.batch_step});
    return Status::Ok();
  };
  const auto add_links_before = [&](int64_t utime) -> Status {
    for (; next_link < links.size() && links[next_link].utime < utime; ++next_link) {
      const AreaReplayLink& l = links[next_link];
      const AreaReplayKeyframe& a = keyframes[static_cast<size_t>(l.a)];
      const AreaReplayKeyframe& b = keyframes[static_cast<size_t>(l.b)];
      const Pose2 measured = link_noise(Between(a.truth, b.truth), kLinkSigma);
      parent[static_cast<size_t>(FindRoot(&parent, a.trajectory))] =
          FindRoot(&parent, b.trajectory);
      if (Status s =
              add_factor(placement[static_cast<size_t>(l.a)], placement[static_cast<size_t>(l.b)],
                         measured, Covariance(kLinkSigma));
          !s.ok()) {
        return s;
      }
    }
    return Status::Ok();
  };

  int64_t last_utime = start;
  size_t replayed = 0;
  for (size_t i = 0; i < keyframes.size(); ++i) {
    const AreaReplayKeyframe& k = keyframes[i];
    if (1e-6 * static_cast<double>(k.utime - start) > options.until_s) break;
    last_utime = k.utime;
    replayed = i + 1;
    for (; k.utime >= next_update; next_update += period) {
      if (Status s = add_links_before(next_update); !s.ok()) return s;
      if (Status s = update(next_update); !s.ok()) return s;
    }
    if (Status s = add_links_before(k.utime); !s.ok()) return s;
    const size_t t = static_cast<size_t>(k.trajectory);
    const int previous = last[t];
    last[t] = static_cast<int>(i);
    // Every keyframe draws its odometry and match noise, so that both graphs see the same.
    const Pose2 odometry =
        previous < 0
            ? Pose2()
            : odometry_noise(Between(keyframes[static_cast<size_t>(previous)].truth, k.truth),
                             kOdometrySigma);
    const Pose2 match_noise_pose = match_noise(Pose2(), kMatchSigma);
    int folded = -1;
    if (options.reduced && previous >= 0) {
      folded = selector.Add(static_cast<int>(i), k.truth, [&](const AreaNodeSelector::Node& node) {
        const int other = keyframes[static_cast<size_t>(node.keyframe)].trajectory;
        return FindRoot(&parent, other) == FindRoot(&parent, k.trajectory);
      });
    } else if (options.reduced) {
      selector.Add(static_cast<int>(i), k.truth, [](const AreaNodeSelector::Node&) {
        return false;  // a trajectory's first keyframe is always a node (its frame's origin)
      });
    }
    Placement& here = placement[i];
    if (folded >= 0) {
      const size_t node = static_cast<size_t>(folded);
      const Pose2 node_truth = keyframes[static_cast<size_t>(selector.node(folded).keyframe)].truth;
      here.node = node_keys[node];
      here.T_node_keyframe = Compose(Between(node_truth, k.truth), match_noise_pose);
      here.folded = true;
    } else {
      // A new node joins the trajectory of its predecessor's node: the smoother ties a pose
      // to its trajectory by a between factor (an encounter alone does not determine it).
      const size_t owner =
          previous < 0 ? t
                       : static_cast<size_t>(
                             placement[static_cast<size_t>(previous)].node.trajectory.value());
      here.node = PoseKey{TrajectoryId(static_cast<int64_t>(owner)), poses[owner]++};
      if (options.reduced) node_keys.push_back(here.node);
      // Local frames are the world's (a trajectory's first pose at its truth): the initial
      // guesses are the truth, for both graphs.
      if (Status s = smoother.AddPose(here.node, k.truth); !s.ok()) return s;
    }
    if (previous >= 0) {
      if (Status s = add_factor(placement[static_cast<size_t>(previous)], here, odometry,
                                Covariance(kOdometrySigma));
          !s.ok()) {
        return s;
      }
    }
  }
  if (Status s = add_links_before(last_utime + 1); !s.ok()) return s;
  if (Status s = update(next_update); !s.ok()) return s;
  if (accuracy == nullptr || replayed == 0) return Status::Ok();
  const auto rmse = [&] {
    double sum = 0.0;
    for (size_t i = 0; i < replayed; ++i) {
      const Pose2 estimate =
          Compose(smoother.GlobalPose(placement[i].node), placement[i].T_node_keyframe);
      sum += (estimate.translation() - keyframes[i].truth.translation()).squaredNorm();
    }
    return std::sqrt(sum / static_cast<double>(replayed));
  };
  accuracy->after_updates_m = rmse();
  if (Status s = smoother.BatchOptimize().status; !s.ok()) return s;
  accuracy->after_batch_m = rmse();
  return Status::Ok();
}

}  // namespace anchormap
