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
  uncorrected_factors_.clear();
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
  if (chi2 <= root * root) return true;
  return path_solve_.SquaredNorm(*r_, new_gradient_, root * root) <= root * root;
}

double Smoother::Impl::GradientAtEstimate() {
  estimate_scratch_.resize(vars_.size());
  for (size_t v = 0; v < vars_.size(); ++v) estimate_scratch_[v] = EstimateOf(static_cast<int>(v));
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
    z = r;
    double rz = R.SolveTransposedInPlace(&z);
    const double stop = tolerance * std::max(chi2, 1e-12);
    // At entry the update may be left as it is (correction_skip_factor); once steps are
    // taken they go on to the tolerance or, out of steps, to that budget (batch_policy.h).
    last_decrease_ = rz;
    const CorrectionEnd end = EndOfCorrection(options_, rz, stop, outer, cg_iterations);
    if (end != CorrectionEnd::kGoOn) return end == CorrectionEnd::kConverged;
    R.SolveInPlace(&z);
    p = z;
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
      z = r;
      const double rz_next = R.SolveTransposedInPlace(&z);
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
