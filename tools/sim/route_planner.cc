#include "tools/sim/route_planner.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <queue>
#include <utility>

namespace anchormap::sim {
namespace {

constexpr float kInfinity = std::numeric_limits<float>::infinity();

// One-dimensional squared Euclidean distance transform of `f` (Felzenszwalb &
// Huttenlocher, "Distance transforms of sampled functions", 2012), in place.
void DistanceTransform1d(std::vector<float>* f_inout, std::vector<int>* v_buf,
                         std::vector<float>* z_buf) {
  std::vector<float>& f = *f_inout;
  const int n = static_cast<int>(f.size());
  std::vector<int>& v = *v_buf;
  std::vector<float>& z = *z_buf;
  v.assign(n, 0);
  z.assign(n + 1, 0.0f);
  std::vector<float> d(n);
  int k = -1;
  for (int q = 0; q < n; ++q) {
    if (f[q] == kInfinity) continue;
    while (k >= 0) {
      const float s = ((f[q] + q * q) - (f[v[k]] + v[k] * v[k])) / (2.0f * (q - v[k]));
      if (s > z[k]) break;
      --k;
    }
    ++k;
    v[k] = q;
    z[k] = k == 0
               ? -kInfinity
               : ((f[q] + q * q) - (f[v[k - 1]] + v[k - 1] * v[k - 1])) / (2.0f * (q - v[k - 1]));
    z[k + 1] = kInfinity;
  }
  if (k < 0) return;  // no finite value: all stay infinite
  int j = 0;
  for (int q = 0; q < n; ++q) {
    while (z[j + 1] < q) ++j;
    d[q] = (q - v[j]) * (q - v[j]) + f[v[j]];
  }
  f = std::move(d);
}

}  // namespace

Status RoutePlannerOptions::Validate() const {
  if (!(resolution_m >= 0.02 && resolution_m <= 1.0))
    return Status::Error("planner resolution must be in [0.02, 1] m");
  if (!(clearance_m > 0.0 && clearance_m < 5.0))
    return Status::Error("clearance must be in (0, 5) m");
  if (!(preferred_clearance_m >= clearance_m))
    return Status::Error("preferred clearance must be >= clearance");
  if (!(wall_cost_weight >= 0.0)) return Status::Error("wall cost weight must be >= 0");
  return Status::Ok();
}

RoutePlanner::RoutePlanner(const FloorPlan& plan, const RoutePlannerOptions& options)
    : options_(options) {
  const double res = options_.resolution_m;
  Eigen::Vector2d low(0.0, 0.0);
  Eigen::Vector2d high(1.0, 1.0);
  bool first = true;
  auto extend = [&](const Eigen::Vector2d& p) {
    low = first ? p : low.cwiseMin(p);
    high = first ? p : high.cwiseMax(p);
    first = false;
  };
  for (const WallSegment& wall : plan.walls) {
    extend(wall.a);
    extend(wall.b);
  }
  if (!plan.mask.empty()) {
    extend(plan.mask.origin);
    extend(plan.mask.origin +
           Eigen::Vector2d(plan.mask.width, plan.mask.height) * plan.mask.resolution_m);
  }
  origin_ = low - Eigen::Vector2d::Constant(2.0 * res);
  width_ = static_cast<int>(std::ceil((high.x() - origin_.x()) / res)) + 2;
  height_ = static_cast<int>(std::ceil((high.y() - origin_.y()) / res)) + 2;
  const size_t cells = static_cast<size_t>(width_) * height_;

  // Obstacle cells: every cell a wall passes through, and every cell not entirely free in
  // the mask (when there is one). f = 0 on obstacles, infinity elsewhere.
  std::vector<float> f(cells, kInfinity);
  auto mark = [&](const Eigen::Vector2d& p) {
    const int index = CellIndex(p);
    if (index >= 0) f[index] = 0.0f;
  };
  for (const WallSegment& wall : plan.walls) {
    const double length = (wall.b - wall.a).norm();
    const int steps = std::max(1, static_cast<int>(std::ceil(length / (0.25 * res))));
    for (int i = 0; i <= steps; ++i) mark(wall.a + (wall.b - wall.a) * (double(i) / steps));
  }
  if (!plan.mask.empty()) {
    const TraversableMask& mask = plan.mask;
    for (size_t index = 0; index < cells; ++index) {
      // Cell corners and centre must all be free pixels.
      const Eigen::Vector2d c = CellCenter(static_cast<int>(index));
      const double h = 0.5 * res * 0.999;
      for (const Eigen::Vector2d& p :
           {c, Eigen::Vector2d(c.x() - h, c.y() - h), Eigen::Vector2d(c.x() + h, c.y() - h),
            Eigen::Vector2d(c.x() - h, c.y() + h), Eigen::Vector2d(c.x() + h, c.y() + h)}) {
        if (!mask.IsFree(p)) f[index] = 0.0f;
      }
    }
    // Pixels smaller than a cell can hide between the points above: mark the cell of
    // every non-free pixel centre too.
    for (int y = 0; y < mask.height; ++y) {
      for (int x = 0; x < mask.width; ++x) {
        if (mask.free[static_cast<size_t>(y) * mask.width + x]) continue;
        mark(mask.origin + Eigen::Vector2d(x + 0.5, y + 0.5) * mask.resolution_m);
      }
    }
  }
  // The raster border is an obstacle too, so that no route leaves the raster.
  for (int x = 0; x < width_; ++x) f[x] = f[cells - 1 - x] = 0.0f;
  for (int y = 0; y < height_; ++y)
    f[static_cast<size_t>(y) * width_] = f[static_cast<size_t>(y) * width_ + width_ - 1] = 0.0f;

  // Separable exact squared distance transform: columns, then rows.
  std::vector<int> v;
  std::vector<float> z;
  std::vector<float> line;
  for (int x = 0; x < width_; ++x) {
    line.resize(height_);
    for (int y = 0; y < height_; ++y) line[y] = f[static_cast<size_t>(y) * width_ + x];
    DistanceTransform1d(&line, &v, &z);
    for (int y = 0; y < height_; ++y) f[static_cast<size_t>(y) * width_ + x] = line[y];
  }
  for (int y = 0; y < height_; ++y) {
    line.assign(f.begin() + static_cast<long>(y) * width_,
                f.begin() + static_cast<long>(y + 1) * width_);
    DistanceTransform1d(&line, &v, &z);
    std::copy(line.begin(), line.end(), f.begin() + static_cast<long>(y) * width_);
  }
  // Conservative clearance for any point of the cell: the wall may lie anywhere in its
  // cell and the point anywhere in this one, so subtract two half diagonals.
  clearance_m_.resize(cells);
  for (size_t i = 0; i < cells; ++i) {
    clearance_m_[i] = std::max(0.0f, static_cast<float>((std::sqrt(f[i]) - std::sqrt(2.0)) * res));
  }

  // Connected traversable regions (8-connected flood fill).
  component_.assign(cells, -1);
  int next_component = 0;
  std::vector<int> stack;
  for (size_t seed = 0; seed < cells; ++seed) {
    if (component_[seed] >= 0 || clearance_m_[seed] < options_.clearance_m) continue;
    component_[seed] = next_component;
    stack.push_back(static_cast<int>(seed));
    while (!stack.empty()) {
      const int index = stack.back();
      stack.pop_back();
      const int cx = index % width_;
      const int cy = index / width_;
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          const int nx = cx + dx;
          const int ny = cy + dy;
          if (nx < 0 || ny < 0 || nx >= width_ || ny >= height_) continue;
          const int neighbour = ny * width_ + nx;
          if (component_[neighbour] >= 0 || clearance_m_[neighbour] < options_.clearance_m)
            continue;
          component_[neighbour] = next_component;
          stack.push_back(neighbour);
        }
      }
    }
    ++next_component;
  }
}

int RoutePlanner::CellIndex(const Eigen::Vector2d& point) const {
  const Eigen::Vector2d cell = (point - origin_) / options_.resolution_m;
  if (!(cell.x() >= 0.0 && cell.y() >= 0.0)) return -1;
  const int ix = static_cast<int>(cell.x());
  const int iy = static_cast<int>(cell.y());
  if (ix >= width_ || iy >= height_) return -1;
  return iy * width_ + ix;
}

Eigen::Vector2d RoutePlanner::CellCenter(int index) const {
  return origin_ +
         Eigen::Vector2d(index % width_ + 0.5, index / width_ + 0.5) * options_.resolution_m;
}

double RoutePlanner::Clearance(const Eigen::Vector2d& point) const {
  const int index = CellIndex(point);
  return index < 0 ? 0.0 : clearance_m_[index];
}

bool RoutePlanner::SegmentIsClear(const Eigen::Vector2d& from, const Eigen::Vector2d& to) const {
  const double length = (to - from).norm();
  const int steps =
      std::max(1, static_cast<int>(std::ceil(length / (0.5 * options_.resolution_m))));
  for (int i = 0; i <= steps; ++i) {
    if (!IsTraversable(from + (to - from) * (static_cast<double>(i) / steps))) return false;
  }
  return true;
}

bool RoutePlanner::Connected(const Eigen::Vector2d& a, const Eigen::Vector2d& b) const {
  const int ia = CellIndex(a);
  const int ib = CellIndex(b);
  return ia >= 0 && ib >= 0 && component_[ia] >= 0 && component_[ia] == component_[ib];
}

bool RoutePlanner::SampleTraversable(Rng& rng, Eigen::Vector2d* point, int max_attempts) const {
  const Eigen::Vector2d extent = Eigen::Vector2d(width_, height_) * options_.resolution_m;
  for (int attempt = 0; attempt < max_attempts; ++attempt) {
    // One draw per statement: a call's argument order is unspecified, and the simulator's
    // streams must not depend on the compiler (gcc's order kept: y, then x).
    const double y = rng.Uniform() * extent.y();
    const double x = rng.Uniform() * extent.x();
    const Eigen::Vector2d candidate = origin_ + Eigen::Vector2d(x, y);
    if (IsTraversable(candidate)) {
      *point = candidate;
      return true;
    }
  }
  return false;
}

std::vector<Eigen::Vector2d> RoutePlanner::Plan(const Eigen::Vector2d& start,
                                                const Eigen::Vector2d& goal) const {
  if (!IsTraversable(start) || !IsTraversable(goal) || !Connected(start, goal)) return {};
  const int start_index = CellIndex(start);
  const int goal_index = CellIndex(goal);
  const double res = options_.resolution_m;
  const double span = std::max(1e-6, options_.preferred_clearance_m - options_.clearance_m);
  auto cost_factor = [&](int index) {
    const double shortfall = std::max(0.0, options_.preferred_clearance_m - clearance_m_[index]);
    return 1.0 + options_.wall_cost_weight * std::min(1.0, shortfall / span);
  };
  auto heuristic = [&](int index) { return (CellCenter(index) - goal).norm(); };

  const size_t cells = clearance_m_.size();
  std::vector<double> cost(cells, std::numeric_limits<double>::infinity());
  std::vector<int> parent(cells, -1);
  std::vector<uint8_t> closed(cells, 0);
  // (estimated total, cell index): ties broken by the smaller index, so plans are
  // identical from run to run.
  using Entry = std::pair<double, int>;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> open;
  cost[start_index] = 0.0;
  open.push({heuristic(start_index), start_index});
  while (!open.empty()) {
    const int index = open.top().second;
    open.pop();
    if (closed[index]) continue;
    closed[index] = 1;
    if (index == goal_index) break;
    const int cx = index % width_;
    const int cy = index / width_;
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        if (dx == 0 && dy == 0) continue;
        const int neighbour = (cy + dy) * width_ + (cx + dx);  // border cells are blocked
        if (closed[neighbour] || clearance_m_[neighbour] < options_.clearance_m) continue;
        const double step = (dx != 0 && dy != 0 ? std::sqrt(2.0) : 1.0) * res;
        const double candidate =
            cost[index] + step * 0.5 * (cost_factor(index) + cost_factor(neighbour));
        if (candidate < cost[neighbour]) {
          cost[neighbour] = candidate;
          parent[neighbour] = index;
          open.push({candidate + heuristic(neighbour), neighbour});
        }
      }
    }
  }
  if (!closed[goal_index]) return {};

  std::vector<Eigen::Vector2d> chain;
  for (int index = parent[goal_index]; index >= 0 && index != start_index; index = parent[index]) {
    chain.push_back(CellCenter(index));
  }
  chain.push_back(start);
  std::reverse(chain.begin(), chain.end());
  chain.push_back(goal);

  // Shortcuts: from each kept point, go as far along the chain as a clear straight line
  // allows (the next point is always allowed, so the route is never lost).
  std::vector<Eigen::Vector2d> route{chain.front()};
  size_t i = 0;
  while (i + 1 < chain.size()) {
    size_t j = i + 1;
    while (j + 1 < chain.size() && SegmentIsClear(chain[i], chain[j + 1])) ++j;
    route.push_back(chain[j]);
    i = j;
  }
  return route;
}

}  // namespace anchormap::sim
