#include "common/scan_matching/lattice_search.h"

#include <algorithm>
#include <cmath>

namespace anchormap {

Pose2 LatticeToPose(const SearchWindow& window, double resolution, const LatticePose& lattice) {
  return Pose2(window.center.x() + lattice.dx * resolution,
               window.center.y() + lattice.dy * resolution,
               window.center.theta() + lattice.k * window.angle_step_rad);
}

double AngleStepForRange(double resolution_m, double max_range_m) {
  if (!(max_range_m > resolution_m)) return 0.1;
  return std::min(0.1, 2.0 * std::asin(0.5 * resolution_m / max_range_m));
}

DiscretisedQuery::DiscretisedQuery(const PointCloud& query, const SearchWindow& window,
                                   const GridGeometry& geometry)
    : half_angles_(window.half_angles), num_points_(query.size()) {
  cells_.resize(2 * window.half_angles + 1);
  for (int k = -window.half_angles; k <= window.half_angles; ++k) {
    const Pose2 pose(window.center.x(), window.center.y(),
                     window.center.theta() + k * window.angle_step_rad);
    const Eigen::Matrix2d R = pose.rotation();
    const Eigen::Vector2d t = pose.translation();
    std::vector<Eigen::Vector2i>& cells = cells_[k + half_angles_];
    cells.reserve(query.size());
    for (const Eigen::Vector2d& p : query) cells.push_back(geometry.CellOf(R * p + t));
  }
}

double ScoreOnLevel(const MaxGridPyramid& grids, int level, const DiscretisedQuery& query, int k,
                    int dx, int dy) {
  const std::vector<Eigen::Vector2i>& cells = query.cells(k);
  if (cells.empty()) return 0.0;
  double sum = 0.0;
  for (const Eigen::Vector2i& c : cells) sum += grids.Value(level, c.x() + dx, c.y() + dy);
  return sum / static_cast<double>(cells.size());
}

std::optional<LatticePose> ExhaustiveSearch(const MaxGridPyramid& grids,
                                            const DiscretisedQuery& query,
                                            const SearchWindow& window, double min_score,
                                            LatticeSearchStats* stats) {
  std::optional<LatticePose> best;
  double best_score = min_score;
  for (int k = -window.half_angles; k <= window.half_angles; ++k) {
    for (int dy = -window.half_cells_y; dy <= window.half_cells_y; ++dy) {
      for (int dx = -window.half_cells_x; dx <= window.half_cells_x; ++dx) {
        const double score = ScoreOnLevel(grids, 0, query, k, dx, dy);
        if (stats != nullptr) {
          ++stats->scored_nodes;
          ++stats->leaves;
        }
        if (score > best_score) {
          best_score = score;
          best = LatticePose{k, dx, dy, score};
        }
      }
    }
  }
  return best;
}

namespace {

struct Node {
  int k;
  int dx;  // lower corner of the block of translations
  int dy;
  double bound;
};

class BranchAndBoundSearch {
 public:
  BranchAndBoundSearch(const MaxGridPyramid& grids, const DiscretisedQuery& query,
                       const SearchWindow& window, double min_score, LatticeSearchStats* stats)
      : grids_(grids), query_(query), window_(window), best_score_(min_score), stats_(stats) {}

  std::optional<LatticePose> Run() {
    const int top = grids_.num_levels() - 1;
    const int step = 1 << top;
    std::vector<Node> roots;
    for (int k = -window_.half_angles; k <= window_.half_angles; ++k) {
      for (int dy = -window_.half_cells_y; dy <= window_.half_cells_y; dy += step) {
        for (int dx = -window_.half_cells_x; dx <= window_.half_cells_x; dx += step) {
          roots.push_back(Node{k, dx, dy, Score(top, k, dx, dy)});
        }
      }
    }
    Descend(top, &roots);
    return best_;
  }

 private:
  double Score(int level, int k, int dx, int dy) {
    if (stats_ != nullptr) {
      ++stats_->scored_nodes;
      if (level == 0) ++stats_->leaves;
    }
    return ScoreOnLevel(grids_, level, query_, k, dx, dy);
  }

  // Nodes of `level`, each a block of 2^level x 2^level translations (cut at the window).
  void Descend(int level, std::vector<Node>* nodes) {
    std::stable_sort(nodes->begin(), nodes->end(),
                     [](const Node& a, const Node& b) { return a.bound > b.bound; });
    for (const Node& node : *nodes) {
      if (!(node.bound > best_score_)) break;  // sorted: no later node can do better
      if (level == 0) {
        best_score_ = node.bound;
        best_ = LatticePose{node.k, node.dx, node.dy, node.bound};
        break;
      }
      const int half = 1 << (level - 1);
      std::vector<Node> children;
      children.reserve(4);
      for (int oy = 0; oy <= half; oy += half) {
        for (int ox = 0; ox <= half; ox += half) {
          const int dx = node.dx + ox;
          const int dy = node.dy + oy;
          if (dx > window_.half_cells_x || dy > window_.half_cells_y) continue;
          children.push_back(Node{node.k, dx, dy, Score(level - 1, node.k, dx, dy)});
        }
      }
      Descend(level - 1, &children);
    }
  }

  const MaxGridPyramid& grids_;
  const DiscretisedQuery& query_;
  const SearchWindow& window_;
  double best_score_;
  LatticeSearchStats* stats_;
  std::optional<LatticePose> best_;
};

}  // namespace

std::optional<LatticePose> BranchAndBound(const MaxGridPyramid& grids,
                                          const DiscretisedQuery& query, const SearchWindow& window,
                                          double min_score, LatticeSearchStats* stats) {
  return BranchAndBoundSearch(grids, query, window, min_score, stats).Run();
}

}  // namespace anchormap
