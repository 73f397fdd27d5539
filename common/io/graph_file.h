#pragma once
// 2D pose-graph files: g2o (VERTEX_SE2 / EDGE_SE2) and TORO (VERTEX2 / EDGE2).
// An edge's measurement is the pose of `to` in the frame of `from`; its information
// matrix is full 3x3 (x, y, theta). Read errors name the file, the line and the reason.

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/util/status.h"

namespace anchormap {

struct GraphVertex {
  int64_t id = 0;
  Pose2 pose;
};

struct GraphEdge {
  int64_t from = 0;
  int64_t to = 0;
  Pose2 measured_T_from_to;
  Eigen::Matrix3d information = Eigen::Matrix3d::Identity();
};

struct PoseGraph {
  std::vector<GraphVertex> vertices;  // may be empty (edges-only files)
  std::vector<GraphEdge> edges;
};

enum class GraphFormat { kG2o, kToro };

// Reads either format (chosen per line by its tag). Blank lines, '#' comments and g2o
// FIX lines are skipped; an unknown tag, a short or non-numeric line, a non-finite value
// or an information matrix that is not symmetric positive definite is an error
// "PATH:LINE: reason".
Status ReadPoseGraph(const std::string& path, PoseGraph* graph);
// Same, from text in memory (`name` is used in error messages).
Status ParsePoseGraph(const std::string& text, const std::string& name, PoseGraph* graph);

Status WritePoseGraph(const std::string& path, const PoseGraph& graph, GraphFormat format);

// Initial guess for poses 0..n-1 of an edges-only graph: compose the odometry edges
// (i, i+1) in order (n = 1 + the largest id). Error if an odometry edge is missing.
Status InitialGuessFromOdometry(const PoseGraph& graph, std::vector<Pose2>* poses);

}  // namespace anchormap
