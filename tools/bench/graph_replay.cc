#include "tools/bench/graph_replay.h"

#include <algorithm>

#include <Eigen/Dense>

namespace anchormap {

GraphReplay::GraphReplay(const PoseGraph& graph, int robots) : robots_(std::max(robots, 1)) {
  int64_t max_id = -1;
  for (const GraphEdge& e : graph.edges) max_id = std::max({max_id, e.from, e.to});
  for (const GraphVertex& v : graph.vertices) max_id = std::max(max_id, v.id);
  num_poses_ = static_cast<int>(max_id + 1);
  robots_ = std::min(robots_, std::max(num_poses_, 1));
  starts_.resize(robots_ + 1);
  for (int r = 0; r <= robots_; ++r) {
    starts_[r] = static_cast<int64_t>(num_poses_) * r / robots_;
  }
  int longest = 0;
  for (int r = 0; r < robots_; ++r) longest = std::max<int>(longest, starts_[r + 1] - starts_[r]);
  steps_.resize(longest);

  if (graph.vertices.size() == static_cast<size_t>(num_poses_)) {
    vertices_.resize(num_poses_);
    for (const GraphVertex& v : graph.vertices) vertices_[v.id] = v.pose;
  }
  std::vector<const GraphEdge*> odometry_of(num_poses_, nullptr);
  for (const GraphEdge& e : graph.edges) {
    const PoseKey a = KeyOf(e.from), b = KeyOf(e.to);
    const bool odometry = e.to == e.from + 1;
    if (odometry && a.trajectory != b.trajectory) continue;  // the cut: dropped
    ++num_edges_;
    if (odometry && !odometry_of[e.to]) {
      odometry_of[e.to] = &e;
      continue;
    }
    if (a.trajectory != b.trajectory) ++num_encounters_;
    steps_[std::max(a.index, b.index)].others.push_back(&e);
  }
  for (int r = 0; r < robots_; ++r) {
    for (int64_t id = starts_[r]; id < starts_[r + 1]; ++id) {
      Step& step = steps_[id - starts_[r]];
      step.new_poses.push_back(id);
      step.odometry.push_back(odometry_of[id]);
    }
  }
}

PoseKey GraphReplay::KeyOf(int64_t id) const {
  const int r =
      static_cast<int>(std::upper_bound(starts_.begin(), starts_.end(), id) - starts_.begin()) - 1;
  return PoseKey{r, static_cast<int32_t>(id - starts_[r])};
}

Status GraphReplay::AddStep(int k, Smoother* smoother, bool initial_from_vertices) const {
  const Step& step = steps_[k];
  for (size_t n = 0; n < step.new_poses.size(); ++n) {
    const PoseKey key = KeyOf(step.new_poses[n]);
    const GraphEdge* odometry = step.odometry[n];
    Pose2 initial;
    if (initial_from_vertices) {
      initial = Between(vertices_[starts_[key.trajectory]], vertices_[step.new_poses[n]]);
    } else if (key.index > 0) {
      if (!odometry)
        return Status::Error("pose " + std::to_string(step.new_poses[n]) + " has no odometry edge");
      initial = Compose(smoother->LocalPose(KeyOf(odometry->from)), odometry->measured_T_from_to);
    }
    if (Status s = smoother->AddPose(key, initial); !s.ok()) return s;
    if (odometry) {
      const Status s =
          smoother->AddBetween(KeyOf(odometry->from), key, odometry->measured_T_from_to,
                               odometry->information.inverse());
      if (!s.ok()) return s;
    }
  }
  for (const GraphEdge* e : step.others) {
    const PoseKey a = KeyOf(e->from), b = KeyOf(e->to);
    const Eigen::Matrix3d covariance = e->information.inverse();
    const Status s = a.trajectory == b.trajectory
                         ? smoother->AddBetween(a, b, e->measured_T_from_to, covariance)
                         : smoother->AddEncounter(a, b, e->measured_T_from_to, covariance);
    if (!s.ok()) return s;
  }
  return Status::Ok();
}

Status GraphReplay::AddAll(Smoother* smoother, bool initial_from_vertices) const {
  if (initial_from_vertices && !has_all_vertices()) {
    return Status::Error("the graph file does not have a vertex for every pose");
  }
  for (int k = 0; k < num_steps(); ++k) {
    if (Status s = AddStep(k, smoother, initial_from_vertices); !s.ok()) return s;
  }
  return Status::Ok();
}

}  // namespace anchormap
