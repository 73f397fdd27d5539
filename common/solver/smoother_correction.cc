// The correction of the estimate toward the nonlinear optimum after an update
// (correction_tolerance; smoother_impl.h): R, linearised at older points, serves as the
// preconditioner of steps computed from the true gradient at the estimate, either as
// fixed-point steps h = -(R^T R)^-1 g or by conjugate gradients on J^T J h = -g.

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <vector>

#include <Eigen/Dense>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include "common/solver/smoother_impl.h"

namespace anchormap {
namespace {

using Vectors = std::vector<Eigen::Vector3d>;

}  // namespace

bool Smoother::Impl::CorrectEstimate() {
  // Converged last time and the new factors agree with the estimate: the gradient is
  // unchanged (new rows only add information), nothing to do.
  const double budget = SkipFactor() * options_.correction_tolerance * std::max(last_chi2_, 1e-12);
  if (correction_converged_ &&
      (KeepsEstimate() ? UncorrectedDecreaseWithin(budget) : innovation_ <= budget)) {
    ++stats_.correction_skips;
    return true;
  }
  // correction_local_hops: near the new factors first; the whole map only if that leaves
  // more than the budget (from the estimate the local steps reached).
  if (correction_converged_ && LocalHops() > 0) {
    const auto local_start = std::chrono::steady_clock::now();
    const bool within = CorrectLocally(budget);
    stats_.correction_seconds += Seconds(local_start);
    if (within) return true;
  }
  uncorrected_factors_.clear();
  ForgetLocalMoves();
  const auto start = std::chrono::steady_clock::now();
  flat_r_.Refresh(*r_);
  const bool converged = options_.correction_cg_iterations > 0 ? CorrectByConjugateGradients()
                                                               : CorrectByFixedPointSteps();
  if (!converged) ++stats_.correction_stalls;
  correction_converged_ = converged;
  // Kept-estimate mode: the decrease still predicted where the correction stopped, to which
  // the next updates' factors add; else the new factors' chi2 since this correction.
  innovation_ = KeepsEstimate() && converged ? last_decrease_ : 0.0;
  stats_.correction_seconds += Seconds(start);
  return converged;
}

bool Smoother::Impl::UncorrectedDecreaseWithin(double budget) {
  // Since the last correction the old variables kept their estimate and R only gained
  // rows, so g = g_last + J^T e of the factors since (J, e at the estimate, the same as
  // when they entered). With R's metric, sqrt(g^T (R^T R)^-1 g) <= sqrt(g_last's
  // decrease) + |R^-T J^T e|: new rows only shrink g_last's share. J^T e is non-zero at
  // those factors' variables only, so R^-T J^T e only on their paths up R (the rows their
  // Givens updates touched), and the solve stops once the budget is exceeded.
  const double root = std::sqrt(budget) - std::sqrt(innovation_);
  if (root < 0.0) return false;
  new_gradient_.clear();
  std::array<Pose2, kMaxFactorKeys> values;
  double chi2 = 0.0;
  for (int64_t id : uncorrected_factors_) {
    if (!counted_in_gradient_[id]) continue;
    const FactorRecord& f = factors_[id];
    for (int j = 0; j < f.num_vars; ++j) values[j] = EstimateOf(f.vars[j]);
    const LinearizedFactor lin = Linearize(f.factor, values.data());
    chi2 += lin.whitened_error.squaredNorm();
    for (int j = 0; j < f.num_vars; ++j) {
      new_gradient_.emplace_back(vars_[f.vars[j]].position,
                                 lin.jacobians[j].transpose() * lin.whitened_error);
    }
  }
  // |R^-T J^T e|^2 <= |e|^2 (the factors are in R): within the budget without a solve.
  if (moved_factors_.empty() && chi2 <= root * root) return true;
  // Factors the last pass counted whose variables a local correction moved since: what
  // they add to g is their term now minus their term at the last pass's values.
  for (int64_t id : moved_factors_) {
    if (!counted_in_gradient_[id]) continue;
    const FactorRecord& f = factors_[id];
    for (int j = 0; j < f.num_vars; ++j) values[j] = EstimateOf(f.vars[j]);
    const LinearizedFactor now = Linearize(f.factor, values.data());
    for (int j = 0; j < f.num_vars; ++j) values[j] = PassValueOf(f.vars[j]);
    const LinearizedFactor then = Linearize(f.factor, values.data());
    for (int j = 0; j < f.num_vars; ++j) {
      new_gradient_.emplace_back(vars_[f.vars[j]].position,
                                 now.jacobians[j].transpose() * now.whitened_error -
                                     then.jacobians[j].transpose() * then.whitened_error);
    }
  }
  return path_solve_.SquaredNorm(*r_, new_gradient_, root * root) <= root * root;
}

bool Smoother::Impl::CorrectLocally(double budget) {
  // The region: the uncorrected factors' variables and those within LocalHops() factor
  // hops, anchors excluded (an anchor's factors are all its trajectory's encounters: the
  // map), breadth first in the order of the factors.
  const int num_vars = static_cast<int>(vars_.size());
  local_index_.resize(num_vars, -1);  // -1 everywhere between calls
  local_factor_.resize(factors_.size(), 0);
  std::vector<int> region;
  auto add = [&](int var) {
    if (local_index_[var] >= 0 || vars_[var].position < 0 || vars_[var].key.is_anchor()) return;
    if (region.size() >= SmootherOptions::kLocalCorrectionMaxVariables) return;
    local_index_[var] = static_cast<int>(region.size());
    region.push_back(var);
  };
  // Seeds: the factors that entered R since the last correction, local or global.
  for (size_t k = std::min(local_seeds_from_, uncorrected_factors_.size());
       k < uncorrected_factors_.size(); ++k) {
    const int64_t id = uncorrected_factors_[k];
    if (!counted_in_gradient_[id]) continue;
    const FactorRecord& f = factors_[id];
    for (int j = 0; j < f.num_vars; ++j) add(f.vars[j]);
  }
  // Many new variables at once (a large team's update): its correction moves whole
  // trajectories, and the bound would mostly fail (the update pays both).
  if (region.size() > SmootherOptions::kLocalCorrectionMaxSeedVariables) {
    for (int var : region) local_index_[var] = -1;
    return false;
  }
  size_t level_begin = 0;
  for (int hop = 0; hop < LocalHops() && level_begin < region.size(); ++hop) {
    const size_t level_end = region.size();
    for (size_t k = level_begin; k < level_end; ++k) {
      for (int64_t id : var_factors_[region[k]]) {
        if (!counted_in_gradient_[id]) continue;
        const FactorRecord& f = factors_[id];
        for (int j = 0; j < f.num_vars; ++j) add(f.vars[j]);
      }
    }
    level_begin = level_end;
  }
  // Eliminated in R's order (CCOLAMD's on the whole graph, restricted to the region).
  std::sort(region.begin(), region.end(),
            [&](int a, int b) { return vars_[a].position < vars_[b].position; });
  for (size_t k = 0; k < region.size(); ++k) local_index_[region[k]] = static_cast<int>(k);
  // The factors that see the region: their errors change with it.
  std::vector<int64_t> seen;
  for (int var : region) {
    for (int64_t id : var_factors_[var]) {
      if (!counted_in_gradient_[id] || local_factor_[id]) continue;
      local_factor_[id] = 1;
      seen.push_back(id);
    }
  }
  for (int64_t id : seen) local_factor_[id] = 0;
  std::sort(seen.begin(), seen.end());
  // The region's values at the last pass (before its first local move since), and the
  // factors the last pass counted that see it: the bound measures them against those.
  pass_index_.resize(num_vars, -1);
  for (int var : region) {
    if (pass_index_[var] >= 0) continue;
    pass_index_[var] = static_cast<int>(pass_values_.size());
    pass_values_.emplace_back(var, EstimateOf(var));
  }
  for (int64_t id : uncorrected_factors_) local_factor_[id] = 1;  // new since the last pass
  for (int64_t id : seen) {
    if (!local_factor_[id]) moved_factors_.push_back(id);
  }
  for (int64_t id : uncorrected_factors_) local_factor_[id] = 0;
  std::sort(moved_factors_.begin(), moved_factors_.end());
  moved_factors_.erase(std::unique(moved_factors_.begin(), moved_factors_.end()),
                       moved_factors_.end());
  const bool solved = SolveRegion(region, seen);
  for (int var : region) local_index_[var] = -1;
  local_seeds_from_ = uncorrected_factors_.size();
  if (!solved) return false;
  return UncorrectedDecreaseWithin(budget);
}

bool Smoother::Impl::SolveRegion(const std::vector<int>& region, const std::vector<int64_t>& seen) {
  // Gauss-Newton on the region, the rest fixed: H = sum J_A^T J_A, g = sum J_A^T e.
  if (region.empty()) return false;
  const int n = static_cast<int>(region.size());
  std::array<Pose2, kMaxFactorKeys> values;
  auto local_chi2 = [&]() {
    double chi2 = 0.0;
    for (int64_t id : seen) {
      const FactorRecord& f = factors_[id];
      for (int j = 0; j < f.num_vars; ++j) values[j] = EstimateOf(f.vars[j]);
      chi2 += FactorChi2(f.factor, values.data());
    }
    return chi2;
  };
  const double stop = options_.correction_tolerance * std::max(last_chi2_, 1e-12);
  std::vector<Eigen::Triplet<double>> triplets;
  Eigen::VectorXd g(3 * n), h(3 * n);
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::NaturalOrdering<int>>
      ldlt;
  for (int it = 0; it < 3; ++it) {
    triplets.clear();
    g.setZero();
    double chi2 = 0.0;
    for (int64_t id : seen) {
      const FactorRecord& f = factors_[id];
      for (int j = 0; j < f.num_vars; ++j) values[j] = EstimateOf(f.vars[j]);
      const LinearizedFactor lin = Linearize(f.factor, values.data());
      chi2 += lin.whitened_error.squaredNorm();
      for (int j = 0; j < f.num_vars; ++j) {
        const int a = local_index_[f.vars[j]];
        if (a < 0) continue;
        g.segment<3>(3 * a).noalias() += lin.jacobians[j].transpose() * lin.whitened_error;
        for (int i = 0; i < f.num_vars; ++i) {
          const int b = local_index_[f.vars[i]];
          if (b < 0 || b > a) continue;  // the lower triangle
          const Eigen::Matrix3d block = lin.jacobians[j].transpose() * lin.jacobians[i];
          for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 3; ++c) {
              if (3 * a + r >= 3 * b + c) triplets.emplace_back(3 * a + r, 3 * b + c, block(r, c));
            }
          }
        }
      }
    }
    Eigen::SparseMatrix<double> H(3 * n, 3 * n);
    H.setFromTriplets(triplets.begin(), triplets.end());
    if (it == 0) ldlt.analyzePattern(H);
    ldlt.factorize(H);
    if (ldlt.info() != Eigen::Success) return false;
    h = -ldlt.solve(g);
    const double predicted = -g.dot(h);
    if (!(predicted > stop)) break;
    for (int k = 0; k < n; ++k) correction_[region[k]] += h.segment<3>(3 * k);
    double after = local_chi2();
    for (int halving = 0; after > chi2 && halving < 3; ++halving) {
      for (int k = 0; k < n; ++k) correction_[region[k]] -= 0.5 * h.segment<3>(3 * k);
      h *= 0.5;
      after = local_chi2();
    }
    if (after > chi2) {
      for (int k = 0; k < n; ++k) correction_[region[k]] -= h.segment<3>(3 * k);
      break;
    }
  }
  return true;
}

Pose2 Smoother::Impl::PassValueOf(int var) const {
  const int k = var < static_cast<int>(pass_index_.size()) ? pass_index_[var] : -1;
  return k >= 0 ? pass_values_[k].second : EstimateOf(var);
}

void Smoother::Impl::ForgetLocalMoves() {
  for (const auto& [var, value] : pass_values_) pass_index_[var] = -1;
  pass_values_.clear();
  moved_factors_.clear();
  local_seeds_from_ = 0;
}

double Smoother::Impl::GradientAtEstimate() {
  estimate_scratch_.resize(vars_.size());
  // delta_ is by position, in another order than the variables: its entries are fetched a
  // few variables ahead (perf: the wait for them was 40 % of this loop's samples).
  constexpr size_t kAhead = 16;
  for (size_t v = 0; v < vars_.size(); ++v) {
    if (v + kAhead < vars_.size()) {
      const int ahead = vars_[v + kAhead].position;
      if (ahead >= 0) __builtin_prefetch(delta_.data() + ahead);
    }
    estimate_scratch_[v] = EstimateOf(static_cast<int>(v));
  }
  return gradient_.Pass(estimate_scratch_, position_to_var_, factors_, counted_in_gradient_,
                        var_factors_);
}

bool Smoother::Impl::CorrectByFixedPointSteps() {
  const int n = r_->size();
  const FlatR& R = flat_r_;
  Vectors g(n), step(n);
  double previous_chi2 = std::numeric_limits<double>::infinity();
  for (int it = 0;; ++it) {
    const double chi2 = GradientAtEstimate();
    g = gradient_.g();
    if (chi2 > previous_chi2) {  // R is too stale to be a preconditioner here: undo
      for (int p = 0; p < n; ++p) correction_[position_to_var_[p]] += step[p];
      return false;
    }
    previous_chi2 = chi2;
    // y = R^-T g; the predicted decrease of chi2 by the step -(R^T R)^-1 g is |y|^2.
    const double decrease = R.SolveTransposedInPlace(&g);
    last_chi2_ = chi2;
    if (decrease <= options_.correction_tolerance * std::max(chi2, 1e-12)) return true;
    if (it == options_.correction_iterations) return false;
    // step = R^-1 y; the estimate moves by -step.
    step = g;
    R.SolveInPlace(&step);
    for (int p = 0; p < n; ++p) correction_[position_to_var_[p]] -= step[p];
    ++stats_.correction_steps;
  }
}

bool Smoother::Impl::CorrectByConjugateGradients() {
  const int n = r_->size();
  const FlatR& R = flat_r_;
  const double tolerance = options_.correction_tolerance;
  const Vectors& g = gradient_.g();
  Vectors r(n), z(n), p(n), q(n), h(n);
  double previous_chi2 = std::numeric_limits<double>::infinity();
  int cg_iterations = 0;
  int halvings = 0;
  for (int outer = 0;; ++outer) {
    // Gradient of chi2 / 2 at the estimate, and the Jacobians there.
    const double chi2 = GradientAtEstimate();
    if (chi2 > previous_chi2) {
      // The Gauss-Newton step overshot (the model is poor this far): halve it, at most
      // three times, then give up.
      const bool halve = halvings++ < 3;
      for (int k = 0; k < n; ++k) {
        if (halve) h[k] *= 0.5;
        correction_[position_to_var_[k]] -= h[k];
      }
      if (!halve) return false;
      continue;
    }
    halvings = 0;
    previous_chi2 = chi2;
    last_chi2_ = chi2;
    // Residual of J^T J h = -g at h = 0, and its preconditioned norm: the decrease of chi2
    // that R^T R predicts for the whole step.
    for (int k = 0; k < n; ++k) r[k] = -g[k];
    double rz = R.SolveTransposed(r, &z);
    const double stop = tolerance * std::max(chi2, 1e-12);
    // At entry the update may be left as it is (correction_skip_factor); once steps are
    // taken they go on to the tolerance or, out of steps, to that budget (batch_policy.h).
    last_decrease_ = rz;
    const CorrectionEnd end = EndOfCorrection(options_, rz, stop, outer, cg_iterations);
    if (end != CorrectionEnd::kGoOn) return end == CorrectionEnd::kConverged;
    R.SolveInPlace(&z);
    p.swap(z);  // z is written again before it is read
    std::fill(h.begin(), h.end(), Eigen::Vector3d::Zero());
    while (cg_iterations < options_.correction_cg_iterations) {
      // q = J^T J p, J the factors in R linearised at the estimate (the last pass's).
      const double pq = gradient_.MultiplyNormal(p, &q);
      ++cg_iterations;
      ++stats_.correction_steps;
      if (!(pq > 0)) break;
      const double alpha = rz / pq;
      for (int k = 0; k < n; ++k) {
        h[k] += alpha * p[k];
        r[k] -= alpha * q[k];
      }
      const double rz_next = R.SolveTransposed(r, &z);
      if (rz_next <= stop) break;
      R.SolveInPlace(&z);
      const double beta = rz_next / rz;
      rz = rz_next;
      for (int k = 0; k < n; ++k) p[k] = z[k] + beta * p[k];
    }
    for (int k = 0; k < n; ++k) correction_[position_to_var_[k]] += h[k];
  }
}

}  // namespace anchormap
