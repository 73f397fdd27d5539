#include "common/io/graph_file.h"

#include <cmath>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <unordered_map>

#include "common/geometry/covariance.h"

namespace anchormap {
namespace {

Status LineError(const std::string& name, int line, const std::string& reason) {
  return Status::Error(name + ":" + std::to_string(line) + ": " + reason);
}

// Reads exactly `count` finite numbers from the rest of the line.
bool ReadNumbers(std::istringstream& in, int count, double* out, std::string* reason) {
  for (int k = 0; k < count; ++k) {
    std::string token;
    if (!(in >> token)) {
      *reason = "expected " + std::to_string(count) + " numbers, found " + std::to_string(k);
      return false;
    }
    char* end = nullptr;
    out[k] = std::strtod(token.c_str(), &end);
    if (end == token.c_str() || *end != '\0') {
      *reason = "'" + token + "' is not a number";
      return false;
    }
    if (!std::isfinite(out[k])) {
      *reason = "value '" + token + "' is not finite";
      return false;
    }
  }
  std::string extra;
  if (in >> extra) {
    *reason = "unexpected trailing '" + extra + "'";
    return false;
  }
  return true;
}

bool ReadId(std::istringstream& in, int64_t* id, std::string* reason) {
  std::string token;
  if (!(in >> token)) {
    *reason = "missing vertex id";
    return false;
  }
  char* end = nullptr;
  const long long value = std::strtoll(token.c_str(), &end, 10);
  if (end == token.c_str() || *end != '\0' || value < 0) {
    *reason = "'" + token + "' is not a vertex id (a non-negative integer)";
    return false;
  }
  *id = value;
  return true;
}

}  // namespace

Status ParsePoseGraph(const std::string& text, const std::string& name, PoseGraph* graph) {
  graph->vertices.clear();
  graph->edges.clear();
  std::istringstream lines(text);
  std::string line;
  int number = 0;
  while (std::getline(lines, line)) {
    ++number;
    std::istringstream in(line);
    std::string tag;
    if (!(in >> tag) || tag[0] == '#' || tag == "FIX") continue;
    std::string reason;
    if (tag == "VERTEX_SE2" || tag == "VERTEX2") {
      GraphVertex vertex;
      double v[3];
      if (!ReadId(in, &vertex.id, &reason) || !ReadNumbers(in, 3, v, &reason)) {
        return LineError(name, number, tag + ": " + reason);
      }
      vertex.pose = Pose2(v[0], v[1], v[2]);
      graph->vertices.push_back(vertex);
    } else if (tag == "EDGE_SE2" || tag == "EDGE2") {
      GraphEdge edge;
      double v[9];
      if (!ReadId(in, &edge.from, &reason) || !ReadId(in, &edge.to, &reason) ||
          !ReadNumbers(in, 9, v, &reason)) {
        return LineError(name, number, tag + ": " + reason);
      }
      if (edge.from == edge.to)
        return LineError(name, number, tag + ": edge from a vertex to itself");
      edge.measured_T_from_to = Pose2(v[0], v[1], v[2]);
      if (tag == "EDGE_SE2") {
        edge.information = InformationFromUpperTriangle(v + 3);  // I11 I12 I13 I22 I23 I33
      } else {
        // TORO: I11 I12 I22 I33 I13 I23.
        const double upper[6] = {v[3], v[4], v[7], v[5], v[8], v[6]};
        edge.information = InformationFromUpperTriangle(upper);
      }
      if (Status problem = CheckSymmetricPositiveDefinite(edge.information); !problem.ok()) {
        return LineError(name, number, tag + ": information " + problem.message());
      }
      graph->edges.push_back(edge);
    } else {
      return LineError(name, number,
                       "unknown element '" + tag + "' (a 2D pose graph has " +
                           "VERTEX_SE2/EDGE_SE2 or VERTEX2/EDGE2 lines)");
    }
  }
  return Status::Ok();
}

Status ReadPoseGraph(const std::string& path, PoseGraph* graph) {
  std::ifstream file(path);
  if (!file) return Status::Error(path + ": cannot open");
  std::ostringstream text;
  text << file.rdbuf();
  return ParsePoseGraph(text.str(), path, graph);
}

Status WritePoseGraph(const std::string& path, const PoseGraph& graph, GraphFormat format) {
  std::ofstream out(path);
  if (!out) return Status::Error(path + ": cannot open for writing");
  out << std::setprecision(17);
  const bool g2o = format == GraphFormat::kG2o;
  for (const GraphVertex& v : graph.vertices) {
    out << (g2o ? "VERTEX_SE2 " : "VERTEX2 ") << v.id << ' ' << v.pose.x() << ' ' << v.pose.y()
        << ' ' << v.pose.theta() << '\n';
  }
  for (const GraphEdge& e : graph.edges) {
    const Eigen::Matrix3d& I = e.information;
    const Pose2& z = e.measured_T_from_to;
    out << (g2o ? "EDGE_SE2 " : "EDGE2 ") << e.from << ' ' << e.to << ' ' << z.x() << ' ' << z.y()
        << ' ' << z.theta() << ' ';
    if (g2o) {
      out << I(0, 0) << ' ' << I(0, 1) << ' ' << I(0, 2) << ' ' << I(1, 1) << ' ' << I(1, 2) << ' '
          << I(2, 2) << '\n';
    } else {
      out << I(0, 0) << ' ' << I(0, 1) << ' ' << I(1, 1) << ' ' << I(2, 2) << ' ' << I(0, 2) << ' '
          << I(1, 2) << '\n';
    }
  }
  if (!out) return Status::Error(path + ": write failed");
  return Status::Ok();
}

Status InitialGuessFromOdometry(const PoseGraph& graph, std::vector<Pose2>* poses) {
  int64_t max_id = -1;
  std::unordered_map<int64_t, const GraphEdge*> odometry;
  for (const GraphEdge& e : graph.edges) {
    max_id = std::max({max_id, e.from, e.to});
    if (e.to == e.from + 1 && !odometry.count(e.from)) odometry[e.from] = &e;
  }
  poses->assign(max_id + 1, Pose2());
  for (int64_t i = 0; i < max_id; ++i) {
    auto it = odometry.find(i);
    if (it == odometry.end()) {
      return Status::Error("no odometry edge " + std::to_string(i) + " -> " +
                           std::to_string(i + 1));
    }
    (*poses)[i + 1] = Compose((*poses)[i], it->second->measured_T_from_to);
  }
  return Status::Ok();
}

}  // namespace anchormap
