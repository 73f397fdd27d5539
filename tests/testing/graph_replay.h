#pragma once
// Replays one recorded pose graph into the smoother as iSAM does (pose by pose), or cut
// into N robots as the thesis' experiment did (docs/METHOD.md section 9): poses 0..n-1 are
// cut into N consecutive pieces of equal length; the odometry edge across each cut is
// dropped. Within a piece, a pose without an odometry edge from its predecessor (a broken
// chain) starts a new trajectory too. Each trajectory lives in its own local frame, and
// edges between two trajectories become encounters (which anchor them: docs/METHOD.md
// section 4).
// Step k adds the k-th pose of every piece, each new pose's odometry edge first, then
// every other edge whose two ends exist.

#include <cstdint>
#include <vector>

#include "common/io/graph_file.h"
#include "common/solver/smoother.h"
#include "common/util/status.h"

namespace anchormap {

class GraphReplay {
 public:
  // Poses are numbered 0..n-1 (n = 1 + the largest id); the odometry edges are (i, i+1).
  // A graph whose ids cannot be replayed (too sparse to number densely) gives a replay
  // with no steps and a failed status().
  GraphReplay(const PoseGraph& graph, int robots);

  const Status& status() const { return status_; }
  int num_steps() const { return static_cast<int>(steps_.size()); }
  int num_poses() const { return num_poses_; }
  int robots() const { return robots_; }
  // Trajectories: one per piece, plus one per broken odometry chain within a piece.
  int num_trajectories() const { return static_cast<int>(starts_.size()) - 1; }
  int num_chain_breaks() const { return num_trajectories() - robots_; }
  // Edges used (all but the dropped cut edges), and how many of them are encounters.
  int num_edges() const { return num_edges_; }
  int num_encounters() const { return num_encounters_; }

  // The trajectory and local index of global pose `id` (0 <= id < num_poses()).
  PoseKey KeyOf(int64_t id) const;
  int64_t GlobalId(PoseKey key) const { return starts_[key.trajectory.value()] + key.index; }

  // Adds step `k` to `smoother`: new poses, initialised by composing their odometry
  // measurement onto the smoother's current estimate of the previous pose (the origin
  // for a trajectory's first pose), then the step's edges.
  // With `initial_from` (which must hold the step's poses), its estimates are the
  // initial guesses (for a batch solve that should end at the optimum nearest to them).
  Status AddStep(int k, Smoother* smoother, bool initial_from_vertices = false,
                 const Smoother* initial_from = nullptr) const;
  // Adds every step without updating (for a batch solve). With `initial_from_vertices`
  // the initial guess is the file's VERTEX values (expressed in each trajectory's first
  // pose) instead of composed odometry; needs a vertex for every pose.
  Status AddAll(Smoother* smoother, bool initial_from_vertices = false) const;
  bool has_all_vertices() const { return vertices_.size() == static_cast<size_t>(num_poses_); }

 private:
  struct Step {
    std::vector<int64_t> new_poses;
    std::vector<const GraphEdge*> odometry;  // odometry edge of each new pose (or null)
    std::vector<const GraphEdge*> others;
  };
  Status status_;
  int robots_;
  int num_poses_ = 0;
  int num_edges_ = 0;
  int num_encounters_ = 0;
  std::vector<int64_t> starts_;  // first global id of each trajectory, then num_poses_
  std::vector<Pose2> vertices_;  // by id, when the file has every vertex
  std::vector<Step> steps_;
};

}  // namespace anchormap
