#include "tests/testing/graph_replay.h"

#include <algorithm>
#include <string>

#include <Eigen/Dense>

namespace anchormap {

GraphReplay::GraphReplay(const PoseGraph& graph, int robots) : robots_(std::max(robots, 1)) {
  int64_t max_id = -1;
  for (const GraphEdge& e : graph.edges) max_id = std::max({max_id, e.from, e.to});
  for (const GraphVertex& v : graph.vertices) max_id = std::max(max_id, v.id);
  // Ids are numbered densely; a file whose ids are far sparser than its content (or do
  // not fit an index) is refused rather than replayed as millions of isolated poses.
  const int64_t content = static_cast<int64_t>(graph.edges.size() + graph.vertices.size());
  if (max_id >= (int64_t{1} << 30) || max_id > 16 * content + 1024) {
    status_ = Status::Error("pose ids up to " + std::to_string(max_id) + " for " +
                            std::to_string(content) + " vertices and edges: not numbered densely");
    robots_ = 1;
    starts_ = {0, 0};
    return;
  }
  num_poses_ = static_cast<int>(max_id + 1);
  robots_ = std::min(robots_, std::max(num_poses_, 1));
  // Pieces (robots) by equal length; each piece's odometry chain, from the first edge
  // (i, i+1) of each i.
  std::vector<int64_t> piece_starts(robots_ + 1);
  for (int r = 0; r <= robots_; ++r) {
    piece_starts[r] = static_cast<int64_t>(num_poses_) * r / robots_;
  }
  auto piece_of = [&](int64_t id) {
    return static_cast<int>(std::upper_bound(piece_starts.begin(), piece_starts.end(), id) -
                            piece_starts.begin()) -
           1;
  };
  auto step_of = [&](int64_t id) { return static_cast<int>(id - piece_starts[piece_of(id)]); };
  std::vector<const GraphEdge*> odometry_of(num_poses_, nullptr);
  for (const GraphEdge& e : graph.edges) {
    if (e.to == e.from + 1 && piece_of(e.from) == piece_of(e.to) && !odometry_of[e.to]) {
      odometry_of[e.to] = &e;
    }
  }
  // Trajectories: a piece's first pose, and every pose without an odometry edge.
  for (int64_t id = 0; id < num_poses_; ++id) {
    if (id == piece_starts[piece_of(id)] || !odometry_of[id]) starts_.push_back(id);
  }
  starts_.push_back(num_poses_);

  if (graph.vertices.size() == static_cast<size_t>(num_poses_)) {
    vertices_.resize(num_poses_);
    for (const GraphVertex& v : graph.vertices) vertices_[v.id] = v.pose;
  }
  int longest = 0;
  for (int r = 0; r < robots_; ++r) {
    longest = std::max<int>(longest, static_cast<int>(piece_starts[r + 1] - piece_starts[r]));
  }
  steps_.resize(longest);
  for (const GraphEdge& e : graph.edges) {
    if (e.to == e.from + 1 && piece_of(e.from) != piece_of(e.to)) continue;  // the cut: dropped
    ++num_edges_;
    if (odometry_of[e.to] == &e) continue;
    if (KeyOf(e.from).trajectory != KeyOf(e.to).trajectory) ++num_encounters_;
    steps_[std::max(step_of(e.from), step_of(e.to))].others.push_back(&e);
  }
  for (int r = 0; r < robots_; ++r) {
    for (int64_t id = piece_starts[r]; id < piece_starts[r + 1]; ++id) {
      Step& step = steps_[id - piece_starts[r]];
      step.new_poses.push_back(id);
      step.odometry.push_back(odometry_of[id]);
    }
  }
}

PoseKey GraphReplay::KeyOf(int64_t id) const {
  const int t =
      static_cast<int>(std::upper_bound(starts_.begin(), starts_.end(), id) - starts_.begin()) - 1;
  return PoseKey{TrajectoryId(t), static_cast<int32_t>(id - starts_[t])};
}

Status GraphReplay::AddStep(int k, Smoother* smoother, bool initial_from_vertices,
                            const Smoother* initial_from) const {
  if (!status_.ok()) return status_;
  const Step& step = steps_[k];
  for (size_t n = 0; n < step.new_poses.size(); ++n) {
    const PoseKey key = KeyOf(step.new_poses[n]);
    const GraphEdge* odometry = key.index > 0 ? step.odometry[n] : nullptr;
    Pose2 initial;
    if (initial_from && initial_from->HasPose(key)) {
      initial = initial_from->FramePose(key);
    } else if (initial_from_vertices) {
      initial = Between(vertices_[starts_[key.trajectory.value()]], vertices_[step.new_poses[n]]);
    } else if (odometry) {
      if (!smoother->HasPose(KeyOf(odometry->from))) {
        return Status::Error("pose " + std::to_string(odometry->from) + " was not added");
      }
      initial = Compose(smoother->FramePose(KeyOf(odometry->from)), odometry->measured_T_from_to);
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
  if (!status_.ok()) return status_;
  if (initial_from_vertices && !has_all_vertices()) {
    return Status::Error("the graph file does not have a vertex for every pose");
  }
  for (int k = 0; k < num_steps(); ++k) {
    if (Status s = AddStep(k, smoother, initial_from_vertices); !s.ok()) return s;
  }
  return Status::Ok();
}

}  // namespace anchormap
