#include "common/solver/linearization_cache.h"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace anchormap {
namespace {

// Bit for bit, so that an unmoved variable's factors give exactly what they gave before.
bool SameBits(const Pose2& a, const Pose2& b) {
  const double ka[3] = {a.x(), a.y(), a.theta()};
  const double kb[3] = {b.x(), b.y(), b.theta()};
  return std::memcmp(ka, kb, sizeof(ka)) == 0;
}

// CosSin::Of(angle), its two entries apart: GCC makes one sincos call of the pair, which
// returns them through memory in 8-byte stores, and a 16-byte copy of the pair then waited
// for those stores (perf: 40 % of BeginPass's samples). Here sincos writes two separate
// variables (the call GCC makes of CosSin::Of: the same bits).
CosSin Rotation(double angle) {
#if defined(__GLIBC__) && defined(__GNUC__)
  double c, s;
  sincos(angle, &s, &c);
  CosSin out;
  out.c = c;
  out.s = s;
  return out;
#else
  return CosSin::Of(angle);
#endif
}

}  // namespace

void LinearizationCache::BeginPass(const std::vector<Pose2>& values, int64_t num_factors) {
  ++passes_;
  if (static_cast<int64_t>(offset_.size()) < num_factors) {
    offset_.resize(num_factors, -1);
    num_keys_.resize(num_factors, 0);
    valid_.resize(num_factors, 0);
  }
  // One sweep: a variable not moved already has its value (bit for bit) and rotation.
  const size_t n = values.size();
  const size_t known = std::min(values_.size(), n);
  moved_.resize(n);
  values_.resize(n);
  rotations_.resize(n);
  for (size_t v = 0; v < n; ++v) {
    const bool moved = v >= known || !SameBits(values[v], values_[v]);
    moved_[v] = moved ? 1 : 0;
    if (moved) {
      values_[v] = values[v];
      rotations_[v] = Rotation(values[v].theta());
    }
  }
}

LinearizedView LinearizationCache::At(int64_t id, const Factor& factor, const int* vars,
                                      int num_vars, double* terms, double* squared) {
  bool fresh = valid_[id] != 0;
  for (int j = 0; j < num_vars && fresh; ++j) fresh = !moved_[vars[j]];
  if (fresh) {
    PackedGradientTerms(store_.data() + offset_[id], num_keys_[id], terms, squared);
    return entry(id);
  }
  if (offset_[id] < 0) {
    offset_[id] = static_cast<int64_t>(store_.size());
    num_keys_[id] = static_cast<unsigned char>(num_vars);
    store_.resize(store_.size() + 3 + 9 * num_vars);
  }
  LinearizePacked(factor, values_.data(), rotations_.data(), vars, store_.data() + offset_[id],
                  terms, squared);
  valid_[id] = 1;
  ++linearized_;
  return entry(id);
}

void LinearizationCache::Skip(int64_t id) {
  if (static_cast<size_t>(id) < valid_.size()) valid_[id] = 0;
}

void LinearizationCache::Clear() {
  values_.clear();
  rotations_.clear();
  moved_.clear();
  store_.clear();
  offset_.clear();
  num_keys_.clear();
  valid_.clear();
}

}  // namespace anchormap
