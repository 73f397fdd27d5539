#include "common/solver/incremental_gradient.h"

#include <algorithm>
#include <cstring>

namespace anchormap {
namespace {

// Eight flags at once: most of a pass's factors did not change.
uint64_t Word(const char* bytes) {
  uint64_t w;
  std::memcpy(&w, bytes, sizeof(w));
  return w;
}

}  // namespace

double IncrementalGradient::Pass(const std::vector<Pose2>& values,
                                 const std::vector<int>& position_to_var,
                                 const std::vector<smoother_internal::FactorRecord>& factors,
                                 const std::vector<char>& counted,
                                 const std::vector<std::vector<int64_t>>& var_factors) {
  const int64_t num_factors = static_cast<int64_t>(factors.size());
  const int num_vars = static_cast<int>(values.size());
  const int n = static_cast<int>(position_to_var.size());
  if (num_factors < static_cast<int64_t>(counted_.size()) ||
      num_vars < static_cast<int>(position_.size())) {
    Clear();  // not a continuation of the last pass's graph
  }
  cache_.BeginPass(values, num_factors);

  // New factors: their variables never change.
  const int64_t known = static_cast<int64_t>(counted_.size());
  factor_vars_.resize(num_factors);
  factor_num_vars_.resize(num_factors);
  counted_.resize(num_factors, 0);
  positions_.resize(num_factors);
  stale_.resize(num_factors, 0);
  term_offset_.resize(num_factors);
  squared_.resize(num_factors, 0.0);
  chi2_prefix_.resize(num_factors, 0.0);
  for (int64_t id = known; id < num_factors; ++id) {
    factor_vars_[id] = factors[id].vars;
    factor_num_vars_[id] = factors[id].num_vars;
    term_offset_[id] = static_cast<int64_t>(terms_.size());
    terms_.resize(terms_.size() + 3 * factors[id].num_vars, 0.0);
  }

  // Positions: variables appended to R keep the others' places; anything else (a
  // reordering) adds every sum again.
  dirty_.resize(num_vars, 0);
  const bool extends = order_.size() <= position_to_var.size() &&
                       std::equal(order_.begin(), order_.end(), position_to_var.begin());
  const int first_new_position = extends ? static_cast<int>(order_.size()) : 0;
  if (!extends) position_.assign(num_vars, -1);
  position_.resize(num_vars, -1);
  for (int p = first_new_position; p < n; ++p) position_[position_to_var[p]] = p;
  order_.assign(position_to_var.begin(), position_to_var.end());
  auto mark = [this](int var) {
    if (position_[var] >= 0 && !dirty_[var]) {
      dirty_[var] = 1;
      dirty_vars_.push_back(var);
    }
  };
  for (int p = first_new_position; p < n; ++p) mark(position_to_var[p]);

  // Factors of moved variables, and factors counted now and not before or the reverse.
  // Few moved (after an update): through their factor lists; many (after a step): by
  // looking at every factor's variables, sequentially, rather than chasing the lists.
  const std::vector<char>& moved = cache_.moved();
  const int num_moved = static_cast<int>(std::count(moved.begin(), moved.end(), 1));
  if (num_moved <= num_vars / 8) {
    for (int var = 0; var < num_vars; ++var) {
      if (!moved[var]) continue;
      for (int64_t f : var_factors[var]) stale_[f] = 1;
    }
  } else {
    for (int64_t id = 0; id < num_factors; ++id) {
      char any = 0;
      for (int j = 0; j < factor_num_vars_[id]; ++j) any |= moved[factor_vars_[id][j]];
      stale_[id] = any;
    }
  }
  // g where a term changed: by variable when few moved, else by scattering every term in
  // this loop (the same additions in the same order, so the same bits either way).
  const bool full = !extends || num_moved > num_vars / 8;
  g_.resize(n);
  if (full) std::fill(g_.begin(), g_.end(), Eigen::Vector3d::Zero());
  int64_t first_changed = known;
  const char* now = counted.data();
  for (int64_t id = 0; id < num_factors; ++id) {
    if (!full && id + 8 <= num_factors && (id & 7) == 0 &&
        ((Word(now + id) ^ Word(counted_.data() + id)) | Word(stale_.data() + id)) == 0) {
      id += 7;
      continue;
    }
    const bool counts = now[id] != 0;
    if (stale_[id] || counts != (counted_[id] != 0)) {
      stale_[id] = 0;
      if (counts) {
        const smoother_internal::FactorRecord& f = factors[id];
        if (!counted_[id] || !extends) {  // else its positions are set
          for (int j = 0; j < f.num_vars; ++j) positions_[id][j] = position_[f.vars[j]];
        }
        cache_.At(id, f.factor, f.vars.data(), f.num_vars, terms_.data() + term_offset_[id],
                  &squared_[id]);
      } else {
        cache_.Skip(id);  // its variables may move unseen before it counts again
      }
      if (counts || counted_[id]) {
        if (!full) {
          for (int j = 0; j < factor_num_vars_[id]; ++j) mark(factor_vars_[id][j]);
        }
        first_changed = std::min(first_changed, id);
      }
      counted_[id] = counts ? 1 : 0;
    } else if (counts && !extends) {
      for (int j = 0; j < factor_num_vars_[id]; ++j)
        positions_[id][j] = position_[factor_vars_[id][j]];
    }
    if (full && counted_[id]) {
      // Entry by entry: the terms may have just been stored so (a wider load would wait).
      const double* term = terms_.data() + term_offset_[id];
      for (int j = 0; j < factor_num_vars_[id]; ++j) {
        double* g = g_[positions_[id][j]].data();
        g[0] += term[3 * j];
        g[1] += term[3 * j + 1];
        g[2] += term[3 * j + 2];
      }
    }
  }
  if (!full) {
    for (int var : dirty_vars_) SumAt(var, var_factors);
  }

  // chi2 from the first changed factor on.
  double chi2 = first_changed > 0 ? chi2_prefix_[first_changed - 1] : 0.0;
  for (int64_t id = first_changed; id < num_factors; ++id) {
    if (counted_[id]) chi2 += squared_[id];
    chi2_prefix_[id] = chi2;
  }
  for (int var : dirty_vars_) dirty_[var] = 0;
  dirty_vars_.clear();
  return chi2;
}

void IncrementalGradient::SumAt(int var, const std::vector<std::vector<int64_t>>& var_factors) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (int64_t f : var_factors[var]) {
    if (!counted_[f]) continue;
    for (int j = 0; j < factor_num_vars_[f]; ++j) {
      if (factor_vars_[f][j] == var) sum += Term(f, j);
    }
  }
  g_[position_[var]] = sum;
}

double IncrementalGradient::MultiplyNormal(const std::vector<Eigen::Vector3d>& p,
                                           std::vector<Eigen::Vector3d>* q) const {
  std::fill(q->begin(), q->end(), Eigen::Vector3d::Zero());
  double pq = 0.0;
  const int64_t num_factors = static_cast<int64_t>(counted_.size());
  for (int64_t id = 0; id < num_factors; ++id) {
    if (!counted_[id]) continue;
    const LinearizedView lin = cache_.entry(id);
    const std::array<int, kMaxFactorKeys>& at = positions_[id];
    Eigen::Vector3d jp = Eigen::Vector3d::Zero();
    for (int j = 0; j < lin.num_keys(); ++j) jp.noalias() += lin.jacobian(j) * p[at[j]];
    pq += jp.squaredNorm();
    for (int j = 0; j < lin.num_keys(); ++j)
      (*q)[at[j]].noalias() += lin.jacobian(j).transpose() * jp;
  }
  return pq;
}

void IncrementalGradient::Clear() {
  cache_.Clear();
  factor_vars_.clear();
  factor_num_vars_.clear();
  counted_.clear();
  positions_.clear();
  stale_.clear();
  terms_.clear();
  term_offset_.clear();
  squared_.clear();
  chi2_prefix_.clear();
  position_.clear();
  dirty_.clear();
  dirty_vars_.clear();
  order_.clear();
  g_.clear();
}

}  // namespace anchormap
