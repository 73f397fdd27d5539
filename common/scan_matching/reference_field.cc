#include "common/scan_matching/reference_field.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>
#include <utility>

#include <Eigen/Eigenvalues>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "common/scan_matching/avx2_dispatch.h"

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

namespace {

// PrimitiveNormal of the primitive whose vertices have normals na and nb.
bool PrimitiveNormalOf(const Eigen::Vector2d& na, const Eigen::Vector2d& nb, Eigen::Vector2d* n) {
  Eigen::Vector2d sum = na + (na.dot(nb) < 0.0 ? -nb : nb);
  if (na.isZero()) sum = nb;
  const double norm = sum.norm();
  if (norm < 1e-9) return false;
  *n = sum / norm;
  return true;
}

// Which consecutive returns of `scan` are one wall (ScanSurface::joined).
std::vector<uint8_t> JoinedReturns(const PointCloud& scan, double max_join_gap_m) {
  const double gap_sq = max_join_gap_m * max_join_gap_m;
  std::vector<uint8_t> joined(scan.size(), 0);
  for (size_t i = 0; i + 1 < scan.size(); ++i) {
    joined[i] = (scan[i + 1] - scan[i]).squaredNorm() <= gap_sq ? 1 : 0;
  }
  return joined;
}

// Point i's normal from itself and its joined neighbours up to kNormalReach steps away (zero
// for a lone return).
Eigen::Vector2d VertexNormal(const PointCloud& scan, const std::vector<uint8_t>& joined, size_t i) {
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
    // The 2x2 closed form (roots of the characteristic polynomial), not the iterative QL:
    // the same direction to ~1e-15, in a fifth of the time (builds at 100 robots spent 2.5 %
    // of the replay in the iterative one); an isotropic scatter gives (1, 0), as before.
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen;
    eigen.computeDirect(scatter);
    normal = eigen.eigenvectors().col(0);  // the smallest eigenvalue's
  }
  return normal;
}

// The normal of the primitive starting at the vertex with normal na whose other end has
// normal nb (the same vertex for a lone return): zero where there is none.
Eigen::Vector2d StartNormal(const Eigen::Vector2d& na, const Eigen::Vector2d& nb) {
  Eigen::Vector2d n = Eigen::Vector2d::Zero();
  if (!PrimitiveNormalOf(na, nb, &n)) n.setZero();
  return n;
}

}  // namespace

ScanSurface MakeScanSurface(PointCloud points, double max_join_gap_m) {
  ScanSurface surface;
  surface.max_join_gap_m = max_join_gap_m;
  surface.points = std::move(points);
  const PointCloud& scan = surface.points;
  surface.joined = JoinedReturns(scan, max_join_gap_m);
  surface.normals.reserve(scan.size());
  for (size_t i = 0; i < scan.size(); ++i) {
    surface.normals.push_back(VertexNormal(scan, surface.joined, i));
  }
  surface.start_normals.reserve(scan.size());
  for (size_t i = 0; i < scan.size(); ++i) {
    const size_t b = surface.joined[i] ? i + 1 : i;
    surface.start_normals.push_back(StartNormal(surface.normals[i], surface.normals[b]));
  }
  return surface;
}

ReferenceField::ReferenceField(const std::vector<PointCloud>& scans,
                               const ReferenceFieldOptions& options)
    : options_(options) {
  // The joins alone: the normals are made below for the vertices of the primitives some cell
  // holds (a third of a submap's vertices hold none at 100 x 180; their normals are read
  // nowhere), each with MakeScanSurface's own arithmetic.
  std::vector<ScanSurface> surfaces(scans.size());
  std::vector<const ScanSurface*> pointers;
  for (size_t k = 0; k < scans.size(); ++k) {
    surfaces[k].max_join_gap_m = options.max_join_gap_m;
    surfaces[k].points = scans[k];
    surfaces[k].joined = JoinedReturns(scans[k], options.max_join_gap_m);
    pointers.push_back(&surfaces[k]);
  }
  Build(pointers);
  if (num_points_ == 0) return;
  // needs[v]: 1 where v ends a stored primitive (its normal is read), 2 where one starts there.
  std::vector<uint8_t> needs(num_points_, 0);
  ForEachStored([&](size_t index, float, float) {
    const int32_t a = primitive_a_[index];
    needs[static_cast<size_t>(a)] = 3;
    needs[static_cast<size_t>(primitive_ends_[static_cast<size_t>(a)])] |= 1;
  });
  size_t first = 0;
  for (const ScanSurface& surface : surfaces) {
    for (size_t i = 0; i < surface.points.size(); ++i) {
      if (needs[first + i]) normals_[first + i] = VertexNormal(surface.points, surface.joined, i);
    }
    first += surface.points.size();
  }
  for (size_t v = 0; v < num_points_; ++v) {
    if (needs[v] & 2) {
      start_normals_[v] = StartNormal(normals_[v], normals_[primitive_ends_[v]]);
    }
  }
}

ReferenceField::ReferenceField(const std::vector<std::shared_ptr<const ScanSurface>>& surfaces,
                               const ReferenceFieldOptions& options)
    : options_(options) {
  std::vector<const ScanSurface*> pointers;
  for (const std::shared_ptr<const ScanSurface>& surface : surfaces) {
    if (surface->max_join_gap_m != options.max_join_gap_m) {
      throw std::invalid_argument("ReferenceField: a surface joined with another max_join_gap_m");
    }
    pointers.push_back(surface.get());
  }
  Build(pointers);
}

void ReferenceField::Build(const std::vector<const ScanSurface*>& surfaces) {
  const ReferenceFieldOptions& options = options_;
  geometry_.resolution = options.resolution_m;
  Eigen::Vector2d lo(std::numeric_limits<double>::infinity(),
                     std::numeric_limits<double>::infinity());
  Eigen::Vector2d hi = -lo;
  for (const ScanSurface* surface : surfaces) {
    for (const Eigen::Vector2d& p : surface->points) {
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
  vy_.reset(new float[geometry_.num_cells()]);
  const float max_sq = static_cast<float>(options.max_distance_m * options.max_distance_m);
  primitive_a_.reset(new int32_t[geometry_.num_cells()]);
  tiles_width_ = (geometry_.width + kTile - 1) >> kTileShift;
  reached_tiles_.assign(
      static_cast<size_t>(tiles_width_) * ((geometry_.height + kTile - 1) >> kTileShift), 0);
  // The squared distance of each cell's stored vector, read only where a primitive was stored
  // (vx_ not NaN; max_sq elsewhere): no fill of its own.
  const std::unique_ptr<float[]> best_sq(new float[geometry_.num_cells()]);
  // The cells' centre x per column, GridGeometry::CellCentre's own arithmetic; three columns
  // more for the vector rows' last four (never stored).
  std::vector<double> centre_x(static_cast<size_t>(geometry_.width) + 3);
  for (int ix = 0; ix < geometry_.width + 3; ++ix) centre_x[ix] = geometry_.CellCentre(ix, 0).x();
  vertices_.reserve(num_points_);
  normals_.reserve(num_points_);
  start_normals_.reserve(num_points_);
  primitive_ends_.reserve(num_points_);
  for (const ScanSurface* surface : surfaces) {
    const PointCloud& scan = surface->points;
    const int first = static_cast<int>(vertices_.size());
    vertices_.insert(vertices_.end(), scan.begin(), scan.end());
    if (surface->normals.empty()) {  // made after the primitives (the scans' constructor)
      normals_.resize(normals_.size() + scan.size(), Eigen::Vector2d::Zero());
      start_normals_.resize(start_normals_.size() + scan.size(), Eigen::Vector2d::Zero());
    } else {
      normals_.insert(normals_.end(), surface->normals.begin(), surface->normals.end());
      start_normals_.insert(start_normals_.end(), surface->start_normals.begin(),
                            surface->start_normals.end());
    }
    for (size_t i = 0; i < scan.size(); ++i) {
      const int a = first + static_cast<int>(i);
      primitive_ends_.push_back(surface->joined[i] ? a + 1 : a);
      AddPrimitive(a, primitive_ends_.back(), centre_x, max_sq, best_sq.get());
    }
  }
}

namespace {

// How far y lies outside [lo, hi] (0 inside): a primitive's box skips the rows whose centre
// lies farther than its reach from the segment's y range. One definition for the scalar and
// vector builds, which must skip the same rows.
inline double DistanceOutside(double y, double lo, double hi) {
  return y < lo ? lo - y : (y > hi ? y - hi : 0.0);
}

#ifdef ANCHORMAP_AVX2_DISPATCH
// AddPrimitive's box of cells, its rows' cells four at a time (each row's last four masked):
// the same IEEE operations in the same order as the scalar loop (no FMA: the target is AVX2
// alone), so the same bits. `centre_x` has three entries past the grid's last column.
struct PrimitiveBox {
  const double* centre_x;
  double origin_y;
  double resolution;
  int width;  // the grid's
  int x0, y0, x1, y1;
  double lo_y, hi_y, reach;  // rows whose centre lies farther than reach from [lo_y, hi_y] skip
  Eigen::Vector2d a;
  Eigen::Vector2d ab;
  double len_sq;
  int32_t a_index;
  float max_sq;
};

__attribute__((target("avx2"))) void AddPrimitiveAvx2(const PrimitiveBox& box, float* best_sq,
                                                      float* vx, float* vy, int32_t* primitive_a) {
  const __m256d ax = _mm256_set1_pd(box.a.x());
  const __m256d ay = _mm256_set1_pd(box.a.y());
  const __m256d abx = _mm256_set1_pd(box.ab.x());
  const __m256d aby = _mm256_set1_pd(box.ab.y());
  const __m256d length_sq = _mm256_set1_pd(box.len_sq);
  const __m256d zero = _mm256_setzero_pd();
  const __m256d one = _mm256_set1_pd(1.0);
  const __m128i ia = _mm_set1_epi32(box.a_index);
  const __m128i lanes = _mm_setr_epi32(0, 1, 2, 3);
  const __m128 unset = _mm_set1_ps(box.max_sq);
  const bool point = box.len_sq <= 0.0;  // ClosestPointOnSegment's own test
  const int first = box.x0;
  const int last = box.x1;
  for (int iy = box.y0; iy <= box.y1; ++iy) {
    const double centre_y = box.origin_y + box.resolution * (iy + 0.5);
    if (!(DistanceOutside(centre_y, box.lo_y, box.hi_y) <= box.reach)) continue;
    const int row_index = iy * box.width;
    const __m256d cy = _mm256_set1_pd(centre_y);
    // (p - a).dot(ab) takes its y term once per row.
    const __m256d dy_term = _mm256_mul_pd(_mm256_sub_pd(cy, ay), aby);
    for (int ix = first; ix <= last; ix += 4) {
      const __m256d cx = _mm256_loadu_pd(box.centre_x + ix);
      __m256d closest_x = ax;
      __m256d closest_y = ay;
      if (!point) {
        const __m256d dot = _mm256_add_pd(_mm256_mul_pd(_mm256_sub_pd(cx, ax), abx), dy_term);
        // std::clamp(dot / len_sq, 0, 1): the quotient only where 0 < dot < len_sq. Elsewhere
        // it is <= 0 (then t is 0 or a signed zero: a + t ab is a, up to the sign of a zero
        // coordinate, which v = closest - centre loses as no cell centre is 0) or >= 1 (then
        // t is 1): division is monotone and exact at 0 and 1.
        const __m256d ratio = _mm256_div_pd(dot, length_sq);
        __m256d t = _mm256_blendv_pd(ratio, one, _mm256_cmp_pd(one, ratio, _CMP_LT_OQ));
        t = _mm256_blendv_pd(t, zero, _mm256_cmp_pd(ratio, zero, _CMP_LT_OQ));
        closest_x = _mm256_add_pd(ax, _mm256_mul_pd(t, abx));
        closest_y = _mm256_add_pd(ay, _mm256_mul_pd(t, aby));
      }
      const __m256d v_x = _mm256_sub_pd(closest_x, cx);
      const __m256d v_y = _mm256_sub_pd(closest_y, cy);
      const __m128 sq =
          _mm256_cvtpd_ps(_mm256_add_pd(_mm256_mul_pd(v_x, v_x), _mm256_mul_pd(v_y, v_y)));
      const int index = row_index + ix;
      // Lanes past `last` neither read nor write the field.
      const __m128i valid = _mm_cmpgt_epi32(_mm_set1_epi32(last - ix + 1), lanes);
      // A cell no primitive reached yet (vx NaN) holds max_sq, whatever best_sq holds.
      const __m128 stored = _mm_maskload_ps(vx + index, valid);
      const __m128 best = _mm_blendv_ps(_mm_maskload_ps(best_sq + index, valid), unset,
                                        _mm_cmpunord_ps(stored, stored));
      const __m128i take = _mm_and_si128(_mm_castps_si128(_mm_cmple_ps(sq, best)), valid);
      _mm_maskstore_ps(best_sq + index, take, sq);
      _mm_maskstore_ps(vx + index, take, _mm256_cvtpd_ps(v_x));
      _mm_maskstore_ps(vy + index, take, _mm256_cvtpd_ps(v_y));
      _mm_maskstore_epi32(primitive_a + index, take, ia);
    }
  }
}

// AddPrimitiveAvx2 with eight cells a step on AVX-512: the same IEEE operations in the same
// order, so the same bits. Its masked loads and stores are single operations (AVX2's masked
// stores were most of AddPrimitiveAvx2's samples): a reference build 1.28-1.35 -> 1.05-1.07 ms
// (anchormap-bench-reference-build). AVX-512F has FMA: the module is built with
// -ffp-contract=off (its CMakeLists.txt), so no multiply and add is fused (no vfmadd).
__attribute__((target("avx512f,avx512vl"))) void AddPrimitiveAvx512(const PrimitiveBox& box,
                                                                    float* best_sq, float* vx,
                                                                    float* vy,
                                                                    int32_t* primitive_a) {
  const __m512d ax = _mm512_set1_pd(box.a.x());
  const __m512d ay = _mm512_set1_pd(box.a.y());
  const __m512d abx = _mm512_set1_pd(box.ab.x());
  const __m512d aby = _mm512_set1_pd(box.ab.y());
  const __m512d length_sq = _mm512_set1_pd(box.len_sq);
  const __m512d zero = _mm512_setzero_pd();
  const __m512d one = _mm512_set1_pd(1.0);
  const __m256i ia = _mm256_set1_epi32(box.a_index);
  const __m256 unset = _mm256_set1_ps(box.max_sq);
  const bool point = box.len_sq <= 0.0;  // ClosestPointOnSegment's own test
  const int first = box.x0;
  const int last = box.x1;
  for (int iy = box.y0; iy <= box.y1; ++iy) {
    const double centre_y = box.origin_y + box.resolution * (iy + 0.5);
    if (!(DistanceOutside(centre_y, box.lo_y, box.hi_y) <= box.reach)) continue;
    const int row_index = iy * box.width;
    const __m512d cy = _mm512_set1_pd(centre_y);
    const __m512d dy_term = _mm512_mul_pd(_mm512_sub_pd(cy, ay), aby);
    for (int ix = first; ix <= last; ix += 8) {
      // Lanes past `last` read and write nothing.
      const int left = last - ix + 1;
      const __mmask8 valid = left >= 8 ? __mmask8(0xFF) : static_cast<__mmask8>((1u << left) - 1);
      const __m512d cx = _mm512_maskz_loadu_pd(valid, box.centre_x + ix);
      __m512d closest_x = ax;
      __m512d closest_y = ay;
      if (!point) {
        // AddPrimitiveAvx2's clamp of the quotient.
        const __m512d dot = _mm512_add_pd(_mm512_mul_pd(_mm512_sub_pd(cx, ax), abx), dy_term);
        const __m512d ratio = _mm512_div_pd(dot, length_sq);
        __m512d t = _mm512_mask_blend_pd(_mm512_cmp_pd_mask(one, ratio, _CMP_LT_OQ), ratio, one);
        t = _mm512_mask_blend_pd(_mm512_cmp_pd_mask(ratio, zero, _CMP_LT_OQ), t, zero);
        closest_x = _mm512_add_pd(ax, _mm512_mul_pd(t, abx));
        closest_y = _mm512_add_pd(ay, _mm512_mul_pd(t, aby));
      }
      const __m512d v_x = _mm512_sub_pd(closest_x, cx);
      const __m512d v_y = _mm512_sub_pd(closest_y, cy);
      // The masked conversions convert every lane (GCC 12 warns on the unmasked one's source).
      const __m256 sq = _mm512_maskz_cvtpd_ps(
          0xFF, _mm512_add_pd(_mm512_mul_pd(v_x, v_x), _mm512_mul_pd(v_y, v_y)));
      const int index = row_index + ix;
      // A cell no primitive reached yet (vx NaN) holds max_sq, whatever best_sq holds.
      const __m256 stored = _mm256_maskz_loadu_ps(valid, vx + index);
      const __m256 best =
          _mm256_mask_blend_ps(_mm256_cmp_ps_mask(stored, stored, _CMP_UNORD_Q),
                               _mm256_maskz_loadu_ps(valid, best_sq + index), unset);
      const __mmask8 take = _mm256_mask_cmp_ps_mask(valid, sq, best, _CMP_LE_OQ);
      _mm256_mask_storeu_ps(best_sq + index, take, sq);
      _mm256_mask_storeu_ps(vx + index, take, _mm512_maskz_cvtpd_ps(0xFF, v_x));
      _mm256_mask_storeu_ps(vy + index, take, _mm512_maskz_cvtpd_ps(0xFF, v_y));
      _mm256_mask_storeu_epi32(primitive_a + index, take, ia);
    }
  }
}

// The field's arrays InterpolateWithNormals reads.
struct FieldArrays {
  const float* vx;
  const float* vy;
  const int32_t* primitive_a;
  const double* start_normals;  // x, y per vertex
  double origin_x;
  double origin_y;
  double resolution;
  int width;
  int height;
};

// InterpolateImpl's blend of the four cell vectors (one coordinate), in its order.
__attribute__((target("avx2"))) inline __m256d Bilinear(__m256d w00, __m256d w10, __m256d w01,
                                                        __m256d w11, __m256d v00, __m256d v10,
                                                        __m256d v01, __m256d v11) {
  return _mm256_add_pd(
      _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(w00, v00), _mm256_mul_pd(w10, v10)),
                    _mm256_mul_pd(w01, v01)),
      _mm256_mul_pd(w11, v11));
}

// InterpolateImpl and NearestNormal for points [begin, n - (n - begin) % 4), four at a time: the
// same IEEE operations in the same order (no FMA: the target is AVX2 alone), so the same bits.
// Lanes the interpolation refuses read cell (0, 0), which exists whenever any lane is inside the
// grid. Where a point is not found its vx, vy, nx and ny are left unspecified (readers test
// `found` first).
__attribute__((target("avx2"))) void InterpolateWithNormalsAvx2(const FieldArrays& f,
                                                                ReferenceField::Lookups* out,
                                                                size_t begin) {
  const size_t n = out->qx.size();
  const __m256d origin_x = _mm256_set1_pd(f.origin_x);
  const __m256d origin_y = _mm256_set1_pd(f.origin_y);
  const __m256d resolution = _mm256_set1_pd(f.resolution);
  const __m256d half = _mm256_set1_pd(0.5);
  const __m256d zero = _mm256_setzero_pd();
  const __m256d one = _mm256_set1_pd(1.0);
  const __m256d width = _mm256_set1_pd(static_cast<double>(f.width));
  const __m256d height = _mm256_set1_pd(static_cast<double>(f.height));
  const __m128i width_i = _mm_set1_epi32(f.width);
  const __m128i height_i = _mm_set1_epi32(f.height);
  const __m128i minus_one = _mm_set1_epi32(-1);
  // Gathers of every lane (the masked forms: GCC's plain ones leave their source undefined).
  const __m128 no_float = _mm_setzero_ps();
  const __m128 all_float = _mm_castsi128_ps(minus_one);
  // A field without points has no normals (null): no offset from a null pointer (UBSan).
  const double* normals_y = f.start_normals == nullptr ? nullptr : f.start_normals + 1;
  for (size_t i = begin; i + 4 <= n; i += 4) {
    // CellOf's quotients, the four cell centres around the point from floor(u - 0.5).
    const __m256d qx =
        _mm256_div_pd(_mm256_sub_pd(_mm256_loadu_pd(&out->qx[i]), origin_x), resolution);
    const __m256d qy =
        _mm256_div_pd(_mm256_sub_pd(_mm256_loadu_pd(&out->qy[i]), origin_y), resolution);
    const __m256d ux = _mm256_sub_pd(qx, half);
    const __m256d uy = _mm256_sub_pd(qy, half);
    const __m256d fx = _mm256_floor_pd(ux);
    const __m256d fy = _mm256_floor_pd(uy);
    // The scalar test's negation; ordered compares fail for NaN and the infinities fail a bound,
    // which is its isfinite test.
    const __m256d inside = _mm256_and_pd(
        _mm256_and_pd(_mm256_cmp_pd(fx, zero, _CMP_GE_OQ), _mm256_cmp_pd(fy, zero, _CMP_GE_OQ)),
        _mm256_and_pd(_mm256_cmp_pd(_mm256_add_pd(fx, one), width, _CMP_LT_OQ),
                      _mm256_cmp_pd(_mm256_add_pd(fy, one), height, _CMP_LT_OQ)));
    if (_mm256_testz_pd(inside, inside)) {
      for (size_t j = 0; j < 4; ++j) out->found[i + j] = 0;
      continue;
    }
    const __m128i ix = _mm256_cvttpd_epi32(_mm256_and_pd(fx, inside));
    const __m128i iy = _mm256_cvttpd_epi32(_mm256_and_pd(fy, inside));
    const __m128i i00 = _mm_add_epi32(_mm_mullo_epi32(iy, width_i), ix);
    const __m128i i01 = _mm_add_epi32(i00, width_i);
    const __m128i i10 = _mm_sub_epi32(i00, minus_one);
    const __m128i i11 = _mm_sub_epi32(i01, minus_one);
    const __m256d v00x = _mm256_cvtps_pd(_mm_mask_i32gather_ps(no_float, f.vx, i00, all_float, 4));
    const __m256d v10x = _mm256_cvtps_pd(_mm_mask_i32gather_ps(no_float, f.vx, i10, all_float, 4));
    const __m256d v01x = _mm256_cvtps_pd(_mm_mask_i32gather_ps(no_float, f.vx, i01, all_float, 4));
    const __m256d v11x = _mm256_cvtps_pd(_mm_mask_i32gather_ps(no_float, f.vx, i11, all_float, 4));
    const __m256d any_nan = _mm256_or_pd(_mm256_cmp_pd(v00x, v10x, _CMP_UNORD_Q),
                                         _mm256_cmp_pd(v01x, v11x, _CMP_UNORD_Q));
    const __m256d found = _mm256_andnot_pd(any_nan, inside);
    const int found_bits = _mm256_movemask_pd(found);
    if (found_bits == 0) {
      for (size_t j = 0; j < 4; ++j) out->found[i + j] = 0;
      continue;
    }
    const __m256d v00y = _mm256_cvtps_pd(_mm_mask_i32gather_ps(no_float, f.vy, i00, all_float, 4));
    const __m256d v10y = _mm256_cvtps_pd(_mm_mask_i32gather_ps(no_float, f.vy, i10, all_float, 4));
    const __m256d v01y = _mm256_cvtps_pd(_mm_mask_i32gather_ps(no_float, f.vy, i01, all_float, 4));
    const __m256d v11y = _mm256_cvtps_pd(_mm_mask_i32gather_ps(no_float, f.vy, i11, all_float, 4));
    const __m256d tx = _mm256_sub_pd(ux, fx);
    const __m256d ty = _mm256_sub_pd(uy, fy);
    const __m256d sx = _mm256_sub_pd(one, tx);
    const __m256d sy = _mm256_sub_pd(one, ty);
    const __m256d w00 = _mm256_mul_pd(sx, sy);
    const __m256d w10 = _mm256_mul_pd(tx, sy);
    const __m256d w01 = _mm256_mul_pd(sx, ty);
    const __m256d w11 = _mm256_mul_pd(tx, ty);
    _mm256_storeu_pd(&out->vx[i], Bilinear(w00, w10, w01, w11, v00x, v10x, v01x, v11x));
    _mm256_storeu_pd(&out->vy[i], Bilinear(w00, w10, w01, w11, v00y, v10y, v01y, v11y));
    // NearestNormal at the point's own cell (CellOf), only where it was found.
    const __m128i found_i = _mm256_cvtpd_epi32(_mm256_and_pd(found, one));  // 1 or 0
    const __m128i cx = _mm256_cvttpd_epi32(_mm256_and_pd(_mm256_floor_pd(qx), inside));
    const __m128i cy = _mm256_cvttpd_epi32(_mm256_and_pd(_mm256_floor_pd(qy), inside));
    const __m128i contains =
        _mm_and_si128(_mm_and_si128(_mm_cmpgt_epi32(cx, minus_one), _mm_cmpgt_epi32(cy, minus_one)),
                      _mm_and_si128(_mm_cmpgt_epi32(width_i, cx), _mm_cmpgt_epi32(height_i, cy)));
    const __m128i cell = _mm_and_si128(_mm_add_epi32(_mm_mullo_epi32(cy, width_i), cx), contains);
    // The primitive's gather does not wait for the vectors' (found): its cells are read
    // wherever they are in the grid, and only found lanes read their normal.
    const __m128i a_any = _mm_mask_i32gather_epi32(minus_one, f.primitive_a, cell, contains, 4);
    const __m128i a = _mm_or_si128(a_any, _mm_cmpeq_epi32(found_i, _mm_setzero_si128()));
    const __m128i has_primitive = _mm_cmpgt_epi32(a, minus_one);
    const __m256d with_primitive = _mm256_castsi256_pd(_mm256_cvtepi32_epi64(has_primitive));
    const __m128i pair = _mm_slli_epi32(_mm_and_si128(a, has_primitive), 1);
    const __m256d nx = _mm256_mask_i32gather_pd(zero, f.start_normals, pair, with_primitive, 8);
    const __m256d ny = _mm256_mask_i32gather_pd(zero, normals_y, pair, with_primitive, 8);
    // A unit normal is never zero; zero marks a lone return.
    const __m256d zero_normal =
        _mm256_and_pd(_mm256_cmp_pd(nx, zero, _CMP_EQ_OQ), _mm256_cmp_pd(ny, zero, _CMP_EQ_OQ));
    const int normal_bits = _mm256_movemask_pd(_mm256_andnot_pd(zero_normal, with_primitive));
    _mm256_storeu_pd(&out->nx[i], nx);
    _mm256_storeu_pd(&out->ny[i], ny);
    for (size_t j = 0; j < 4; ++j) {
      out->found[i + j] = static_cast<uint8_t>((found_bits >> j) & 1);
      out->has_normal[i + j] = static_cast<uint8_t>((normal_bits >> j) & 1);
    }
  }
}

// Eight floats at 32-bit indices, as doubles (every lane read: the masked form, whose source is
// defined).
__attribute__((target("avx512f,avx512vl"))) inline __m512d GatherAsDoubles(const float* base,
                                                                           __m256i index) {
  return _mm512_maskz_cvtps_pd(
      0xFF, _mm256_mmask_i32gather_ps(_mm256_setzero_ps(), 0xFF, index, base, 4));
}

// InterpolateWithNormalsAvx2 for points [0, n - n % 8), eight at a time on AVX-512 (F and VL):
// the same IEEE operations in the same order, without FMA contraction (-ffp-contract=off for the
// module: AVX-512F has FMA), so the same bits; returns the points done.
__attribute__((target("avx512f,avx512vl"))) size_t InterpolateWithNormalsAvx512(
    const FieldArrays& f, ReferenceField::Lookups* out) {
  const size_t n = out->qx.size();
  const __m512d origin_x = _mm512_set1_pd(f.origin_x);
  const __m512d origin_y = _mm512_set1_pd(f.origin_y);
  const __m512d resolution = _mm512_set1_pd(f.resolution);
  const __m512d half = _mm512_set1_pd(0.5);
  const __m512d zero = _mm512_setzero_pd();
  const __m512d one = _mm512_set1_pd(1.0);
  const __m512d width = _mm512_set1_pd(static_cast<double>(f.width));
  const __m512d height = _mm512_set1_pd(static_cast<double>(f.height));
  const __m256i width_i = _mm256_set1_epi32(f.width);
  const __m256i height_i = _mm256_set1_epi32(f.height);
  const __m256i minus_one = _mm256_set1_epi32(-1);
  const double* normals_y = f.start_normals == nullptr ? nullptr : f.start_normals + 1;
  size_t i = 0;
  for (; i + 8 <= n; i += 8) {
    const __m512d qx =
        _mm512_div_pd(_mm512_sub_pd(_mm512_loadu_pd(&out->qx[i]), origin_x), resolution);
    const __m512d qy =
        _mm512_div_pd(_mm512_sub_pd(_mm512_loadu_pd(&out->qy[i]), origin_y), resolution);
    const __m512d ux = _mm512_sub_pd(qx, half);
    const __m512d uy = _mm512_sub_pd(qy, half);
    const __m512d fx =
        _mm512_maskz_roundscale_pd(0xFF, ux, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC);
    const __m512d fy =
        _mm512_maskz_roundscale_pd(0xFF, uy, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC);
    const __mmask8 inside = _mm512_cmp_pd_mask(fx, zero, _CMP_GE_OQ) &
                            _mm512_cmp_pd_mask(fy, zero, _CMP_GE_OQ) &
                            _mm512_cmp_pd_mask(_mm512_add_pd(fx, one), width, _CMP_LT_OQ) &
                            _mm512_cmp_pd_mask(_mm512_add_pd(fy, one), height, _CMP_LT_OQ);
    if (inside == 0) {
      for (size_t j = 0; j < 8; ++j) out->found[i + j] = 0;
      continue;
    }
    const __m256i ix = _mm512_maskz_cvttpd_epi32(0xFF, _mm512_maskz_mov_pd(inside, fx));
    const __m256i iy = _mm512_maskz_cvttpd_epi32(0xFF, _mm512_maskz_mov_pd(inside, fy));
    const __m256i i00 = _mm256_add_epi32(_mm256_mullo_epi32(iy, width_i), ix);
    const __m256i i01 = _mm256_add_epi32(i00, width_i);
    const __m256i i10 = _mm256_sub_epi32(i00, minus_one);
    const __m256i i11 = _mm256_sub_epi32(i01, minus_one);
    const __m512d v00x = GatherAsDoubles(f.vx, i00);
    const __m512d v10x = GatherAsDoubles(f.vx, i10);
    const __m512d v01x = GatherAsDoubles(f.vx, i01);
    const __m512d v11x = GatherAsDoubles(f.vx, i11);
    const __mmask8 any_nan =
        _mm512_cmp_pd_mask(v00x, v10x, _CMP_UNORD_Q) | _mm512_cmp_pd_mask(v01x, v11x, _CMP_UNORD_Q);
    const __mmask8 found = static_cast<__mmask8>(inside & ~any_nan);
    if (found == 0) {
      for (size_t j = 0; j < 8; ++j) out->found[i + j] = 0;
      continue;
    }
    const __m512d v00y = GatherAsDoubles(f.vy, i00);
    const __m512d v10y = GatherAsDoubles(f.vy, i10);
    const __m512d v01y = GatherAsDoubles(f.vy, i01);
    const __m512d v11y = GatherAsDoubles(f.vy, i11);
    const __m512d tx = _mm512_sub_pd(ux, fx);
    const __m512d ty = _mm512_sub_pd(uy, fy);
    const __m512d sx = _mm512_sub_pd(one, tx);
    const __m512d sy = _mm512_sub_pd(one, ty);
    const __m512d w00 = _mm512_mul_pd(sx, sy);
    const __m512d w10 = _mm512_mul_pd(tx, sy);
    const __m512d w01 = _mm512_mul_pd(sx, ty);
    const __m512d w11 = _mm512_mul_pd(tx, ty);
    // Bilinear's blend, in its order.
    _mm512_storeu_pd(&out->vx[i],
                     _mm512_add_pd(_mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(w00, v00x),
                                                               _mm512_mul_pd(w10, v10x)),
                                                 _mm512_mul_pd(w01, v01x)),
                                   _mm512_mul_pd(w11, v11x)));
    _mm512_storeu_pd(&out->vy[i],
                     _mm512_add_pd(_mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(w00, v00y),
                                                               _mm512_mul_pd(w10, v10y)),
                                                 _mm512_mul_pd(w01, v01y)),
                                   _mm512_mul_pd(w11, v11y)));
    // NearestNormal at the point's own cell (CellOf), only where it was found.
    const __m256i cx = _mm512_maskz_cvttpd_epi32(
        0xFF,
        _mm512_maskz_mov_pd(inside, _mm512_maskz_roundscale_pd(
                                        0xFF, qx, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC)));
    const __m256i cy = _mm512_maskz_cvttpd_epi32(
        0xFF,
        _mm512_maskz_mov_pd(inside, _mm512_maskz_roundscale_pd(
                                        0xFF, qy, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC)));
    const __mmask8 contains =
        _mm256_cmpgt_epi32_mask(cx, minus_one) & _mm256_cmpgt_epi32_mask(cy, minus_one) &
        _mm256_cmpgt_epi32_mask(width_i, cx) & _mm256_cmpgt_epi32_mask(height_i, cy);
    const __m256i cell =
        _mm256_maskz_mov_epi32(contains, _mm256_add_epi32(_mm256_mullo_epi32(cy, width_i), cx));
    // Lanes not found, or whose cell lies outside the grid, hold -1 (no primitive).
    const __m256i a = _mm256_mmask_i32gather_epi32(
        minus_one, static_cast<__mmask8>(contains & found), cell, f.primitive_a, 4);
    const __mmask8 with_primitive = _mm256_cmpgt_epi32_mask(a, minus_one);
    const __m256i pair = _mm256_slli_epi32(_mm256_maskz_mov_epi32(with_primitive, a), 1);
    const __m512d nx = _mm512_mask_i32gather_pd(zero, with_primitive, pair, f.start_normals, 8);
    const __m512d ny = _mm512_mask_i32gather_pd(zero, with_primitive, pair, normals_y, 8);
    // A unit normal is never zero; zero marks a lone return.
    const __mmask8 zero_normal =
        _mm512_cmp_pd_mask(nx, zero, _CMP_EQ_OQ) & _mm512_cmp_pd_mask(ny, zero, _CMP_EQ_OQ);
    const __mmask8 normal = static_cast<__mmask8>(with_primitive & ~zero_normal);
    _mm512_storeu_pd(&out->nx[i], nx);
    _mm512_storeu_pd(&out->ny[i], ny);
    for (size_t j = 0; j < 8; ++j) {
      out->found[i + j] = static_cast<uint8_t>((found >> j) & 1);
      out->has_normal[i + j] = static_cast<uint8_t>((normal >> j) & 1);
    }
  }
  return i;
}
#endif

}  // namespace

void ReferenceField::Lookups::resize(size_t n) {
  qx.resize(n);
  qy.resize(n);
  vx.resize(n);
  vy.resize(n);
  nx.resize(n);
  ny.resize(n);
  found.resize(n);
  has_normal.resize(n);
}

void ReferenceField::InterpolateWithNormals(Lookups* lookups) const {
  const size_t n = lookups->qx.size();
  size_t i = 0;
#ifdef ANCHORMAP_AVX2_DISPATCH
  if (CpuHasAvx2() && !vx_.empty()) {
    const FieldArrays arrays{
        vx_.data(),           vy_.get(),
        primitive_a_.get(),   start_normals_.empty() ? nullptr : start_normals_.front().data(),
        geometry_.origin.x(), geometry_.origin.y(),
        geometry_.resolution, geometry_.width,
        geometry_.height};
    if (CpuHasAvx512()) i = InterpolateWithNormalsAvx512(arrays, lookups);
    InterpolateWithNormalsAvx2(arrays, lookups, i);
    i = n - (n - i) % 4;
  }
#endif
  for (; i < n; ++i) {
    Eigen::Vector2d v = Eigen::Vector2d::Zero();
    Eigen::Vector2i cell = Eigen::Vector2i::Zero();
    Eigen::Vector2d normal = Eigen::Vector2d::Zero();
    lookups->found[i] = InterpolateInCell({lookups->qx[i], lookups->qy[i]}, &v, &cell);
    lookups->has_normal[i] = lookups->found[i] && NearestNormal(cell.x(), cell.y(), &normal);
    lookups->vx[i] = v.x();
    lookups->vy[i] = v.y();
    lookups->nx[i] = normal.x();
    lookups->ny[i] = normal.y();
  }
}

void ReferenceField::AddPrimitive(int a_index, int b_index, const std::vector<double>& centre_x,
                                  float max_sq, float* best) {
  const Eigen::Vector2d& a = vertices_[a_index];
  const Eigen::Vector2d& b = vertices_[b_index];
  const double d = options_.max_distance_m;
  const Eigen::Vector2i c0 = geometry_.CellOf(a.cwiseMin(b).array() - d);
  const Eigen::Vector2i c1 = geometry_.CellOf(a.cwiseMax(b).array() + d);
  const int x0 = std::max(c0.x(), 0);
  const int y0 = std::max(c0.y(), 0);
  const int x1 = std::min(c1.x(), geometry_.width - 1);
  const int y1 = std::min(c1.y(), geometry_.height - 1);
  // Only cells within d of the segment can pass `sq <= best` (best starts at d^2 as a float):
  // the box's rows whose centres lie farther than that from the segment's y range are skipped
  // (the reach is padded far above the float rounding of the squared distances).
  const double reach = d * (1.0 + 1e-6) + 1e-9;
  const double r = geometry_.resolution;
  if (x0 > x1 || y0 > y1) return;
  MarkTiles(x0, y0, x1, y1);
  const double lo_y = std::min(a.y(), b.y());
  const double hi_y = std::max(a.y(), b.y());
  const Eigen::Vector2d ab = b - a;
  const double len_sq = ab.squaredNorm();
#ifdef ANCHORMAP_AVX2_DISPATCH
  if (CpuHasAvx2()) {
    const PrimitiveBox box{centre_x.data(),
                           geometry_.origin.y(),
                           r,
                           geometry_.width,
                           x0,
                           y0,
                           x1,
                           y1,
                           lo_y,
                           hi_y,
                           reach,
                           a,
                           ab,
                           len_sq,
                           a_index,
                           max_sq};
    if (CpuHasAvx512()) {
      AddPrimitiveAvx512(box, best, vx_.data(), vy_.get(), primitive_a_.get());
    } else {
      AddPrimitiveAvx2(box, best, vx_.data(), vy_.get(), primitive_a_.get());
    }
    return;
  }
#endif
  for (int iy = y0; iy <= y1; ++iy) {
    const double centre_y = geometry_.origin.y() + r * (iy + 0.5);
    if (!(DistanceOutside(centre_y, lo_y, hi_y) <= reach)) continue;
    const int row_index = geometry_.Index(0, iy);
    for (int ix = x0; ix <= x1; ++ix) {
      // geometry_.CellCentre(ix, iy), its x from the table (the same bits).
      const Eigen::Vector2d centre(centre_x[ix], centre_y);
      const Eigen::Vector2d v = ClosestPointOnSegment(centre, a, b) - centre;
      const float sq = static_cast<float>(v.squaredNorm());
      const int index = row_index + ix;
      if (sq <= (std::isnan(vx_[index]) ? max_sq : best[index])) {
        best[index] = sq;
        vx_[index] = static_cast<float>(v.x());
        vy_[index] = static_cast<float>(v.y());
        primitive_a_[index] = a_index;
      }
    }
  }
}

uint32_t ReferenceField::StoredBits(size_t index) const {
  static_assert(kTile == 8, "two runs of four cells");
#if defined(__SSE2__)
  const __m128 lo = _mm_loadu_ps(vx_.data() + index);
  const __m128 hi = _mm_loadu_ps(vx_.data() + index + 4);
  return static_cast<uint32_t>(_mm_movemask_ps(_mm_cmpord_ps(lo, lo)) |
                               (_mm_movemask_ps(_mm_cmpord_ps(hi, hi)) << 4));
#else
  uint32_t bits = 0;
  for (int k = 0; k < kTile; ++k) bits |= std::isnan(vx_[index + k]) ? 0u : 1u << k;
  return bits;
#endif
}

void ReferenceField::MarkTiles(int x0, int y0, int x1, int y1) {
  for (int ty = y0 >> kTileShift; ty <= (y1 >> kTileShift); ++ty) {
    uint8_t* row = reached_tiles_.data() + static_cast<size_t>(ty) * tiles_width_;
    for (int tx = x0 >> kTileShift; tx <= (x1 >> kTileShift); ++tx) row[tx] = 1;
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
  if (std::isnan(vx_[index])) return false;  // no primitive stored (primitive_a_ unset)
  *a = primitive_a_[index];
  *b = primitive_ends_[static_cast<size_t>(*a)];
  return true;
}

bool ReferenceField::PrimitiveNormal(int a, int b, Eigen::Vector2d* n) const {
  return PrimitiveNormalOf(normals_[a], normals_[b], n);
}

}  // namespace anchormap
