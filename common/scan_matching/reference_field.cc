#include "common/scan_matching/reference_field.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>

namespace anchormap {

namespace {
// A vertex's normal is fitted to itself and its joined neighbours up to this many beams away.
constexpr size_t kNormalReach = 5;
}  // namespace

Status ReferenceFieldOptions::Validate() const {
  if (!(resolution_m > 0.0) || !std::isfinite(resolution_m))
    return Status::Error("resolution_m must be > 0");
  if (!(max_distance_m >= resolution_m) || !std::isfinite(max_distance_m)) {
    return Status::Error("max_distance_m must be finite and >= resolution_m");
  }
  if (!(max_join_gap_m >= 0.0) || !std::isfinite(max_join_gap_m)) {
    return Status::Error("max_join_gap_m must be finite and >= 0");
  }
  if (!(margin_m >= 0.0) || !std::isfinite(margin_m))
    return Status::Error("margin_m must be finite and >= 0");
  return Status::Ok();
}

Eigen::Vector2d ClosestPointOnSegment(const Eigen::Vector2d& p, const Eigen::Vector2d& a,
                                      const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double len_sq = ab.squaredNorm();
  if (len_sq <= 0.0) return a;
  const double t = std::clamp((p - a).dot(ab) / len_sq, 0.0, 1.0);
  return a + t * ab;
}

ReferenceField::ReferenceField(const std::vector<PointCloud>& scans,
                               const ReferenceFieldOptions& options)
    : options_(options) {
  geometry_.resolution = options.resolution_m;
  Eigen::Vector2d lo(std::numeric_limits<double>::infinity(),
                     std::numeric_limits<double>::infinity());
  Eigen::Vector2d hi = -lo;
  for (const PointCloud& scan : scans) {
    for (const Eigen::Vector2d& p : scan) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
      ++num_points_;
    }
  }
  if (num_points_ == 0) return;
  const double pad = options.margin_m + options.max_distance_m;
  const double r = options.resolution_m;
  geometry_.origin = ((lo.array() - pad) / r).floor().matrix() * r;
  geometry_.width = static_cast<int>(std::ceil((hi.x() + pad - geometry_.origin.x()) / r)) + 1;
  geometry_.height = static_cast<int>(std::ceil((hi.y() + pad - geometry_.origin.y()) / r)) + 1;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  vx_.assign(geometry_.num_cells(), nan);
  vy_.assign(geometry_.num_cells(), nan);
  const float max_sq = static_cast<float>(options.max_distance_m * options.max_distance_m);
  primitive_a_.assign(geometry_.num_cells(), -1);
  primitive_b_.assign(geometry_.num_cells(), -1);
  std::vector<float> best_sq(geometry_.num_cells(), max_sq);
  const double gap_sq = options.max_join_gap_m * options.max_join_gap_m;
  vertices_.reserve(num_points_);
  normals_.reserve(num_points_);
  start_normals_.reserve(num_points_);
  std::vector<uint8_t> joined;
  for (const PointCloud& scan : scans) {
    const int first = static_cast<int>(vertices_.size());
    vertices_.insert(vertices_.end(), scan.begin(), scan.end());
    joined.assign(scan.size(), 0);  // joined[i]: points i and i + 1 are one wall
    for (size_t i = 0; i + 1 < scan.size(); ++i) {
      joined[i] = (scan[i + 1] - scan[i]).squaredNorm() <= gap_sq ? 1 : 0;
    }
    for (size_t i = 0; i < scan.size(); ++i) {
      const int a = first + static_cast<int>(i);
      AddPrimitive(a, joined[i] ? a + 1 : a, &best_sq);
      // The vertex's normal from itself and its joined neighbours up to two steps away.
      size_t lo = i;
      size_t hi = i;
      while (lo > 0 && i - lo < kNormalReach && joined[lo - 1]) --lo;
      while (hi + 1 < scan.size() && hi - i < kNormalReach && joined[hi]) ++hi;
      Eigen::Vector2d normal = Eigen::Vector2d::Zero();
      if (hi > lo) {
        Eigen::Vector2d mean = Eigen::Vector2d::Zero();
        for (size_t k = lo; k <= hi; ++k) mean += scan[k];
        mean /= static_cast<double>(hi - lo + 1);
        Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
        for (size_t k = lo; k <= hi; ++k) {
          scatter += (scan[k] - mean) * (scan[k] - mean).transpose();
        }
        const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(scatter);
        normal = eigen.eigenvectors().col(0);  // the smallest eigenvalue's
      }
      normals_.push_back(normal);
    }
    for (size_t i = 0; i < scan.size(); ++i) {
      const int a = first + static_cast<int>(i);
      Eigen::Vector2d n = Eigen::Vector2d::Zero();
      if (!PrimitiveNormal(a, joined[i] ? a + 1 : a, &n)) n.setZero();
      start_normals_.push_back(n);
    }
  }
}

void ReferenceField::AddPrimitive(int a_index, int b_index, std::vector<float>* best_sq) {
  const Eigen::Vector2d& a = vertices_[a_index];
  const Eigen::Vector2d& b = vertices_[b_index];
  const double d = options_.max_distance_m;
  const Eigen::Vector2i c0 = geometry_.CellOf(a.cwiseMin(b).array() - d);
  const Eigen::Vector2i c1 = geometry_.CellOf(a.cwiseMax(b).array() + d);
  const int x0 = std::max(c0.x(), 0);
  const int y0 = std::max(c0.y(), 0);
  const int x1 = std::min(c1.x(), geometry_.width - 1);
  const int y1 = std::min(c1.y(), geometry_.height - 1);
  for (int iy = y0; iy <= y1; ++iy) {
    for (int ix = x0; ix <= x1; ++ix) {
      const Eigen::Vector2d centre = geometry_.CellCentre(ix, iy);
      const Eigen::Vector2d v = ClosestPointOnSegment(centre, a, b) - centre;
      const float sq = static_cast<float>(v.squaredNorm());
      const int index = geometry_.Index(ix, iy);
      if (sq <= (*best_sq)[index]) {
        (*best_sq)[index] = sq;
        vx_[index] = static_cast<float>(v.x());
        vy_[index] = static_cast<float>(v.y());
        primitive_a_[index] = a_index;
        primitive_b_[index] = b_index;
      }
    }
  }
}

bool ReferenceField::NearestVector(int ix, int iy, Eigen::Vector2d* v) const {
  if (!geometry_.Contains(ix, iy)) return false;
  const int index = geometry_.Index(ix, iy);
  if (std::isnan(vx_[index])) return false;
  *v = {vx_[index], vy_[index]};
  return true;
}

bool ReferenceField::NearestPrimitive(int ix, int iy, int* a, int* b) const {
  if (!geometry_.Contains(ix, iy)) return false;
  const int index = geometry_.Index(ix, iy);
  if (primitive_a_[index] < 0) return false;
  *a = primitive_a_[index];
  *b = primitive_b_[index];
  return true;
}

bool ReferenceField::PrimitiveNormal(int a, int b, Eigen::Vector2d* n) const {
  const Eigen::Vector2d& na = normals_[a];
  const Eigen::Vector2d& nb = normals_[b];
  Eigen::Vector2d sum = na + (na.dot(nb) < 0.0 ? -nb : nb);
  if (na.isZero()) sum = nb;
  const double norm = sum.norm();
  if (norm < 1e-9) return false;
  *n = sum / norm;
  return true;
}

}  // namespace anchormap
