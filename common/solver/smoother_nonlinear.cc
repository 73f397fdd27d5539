// The iterations of a batch step: Gauss-Newton and Powell's dog-leg (smoother_impl.h).

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>

#include <Eigen/Dense>

#include "common/solver/smoother_impl.h"

namespace anchormap {

double Smoother::Impl::Chi2Of(const std::vector<int64_t>& included,
                              const std::vector<Eigen::Vector3d>& step) const {
  double chi2 = 0.0;
  std::array<Pose2, kMaxFactorKeys> values;
  for (int64_t id : included) {
    const FactorRecord& f = factors_[id];
    for (int j = 0; j < f.num_vars; ++j) {
      const Variable& v = vars_[f.vars[j]];
      values[j] = step.empty() ? v.linearization : Retract(v.linearization, step[v.position]);
    }
    chi2 += FactorChi2(f.factor, values.data());
  }
  return chi2;
}

void Smoother::Impl::GaussNewtonIterations(const std::vector<int64_t>& included, int max_iterations,
                                           UpdateResult* result) {
  // R stays linearised at the last point; the final delta is kept (not folded into the
  // linearisation point) so that incremental updates continue consistently from R.
  for (int it = 0; it < max_iterations; ++it) {
    if (it > 0) {
      for (int var : position_to_var_) {
        Variable& v = vars_[var];
        v.linearization = Retract(v.linearization, delta_[v.position]);
      }
    }
    double chi2 = 0.0, predicted_decrease = 0.0;
    if (!FactorAll(included, result, &chi2, &predicted_decrease)) return;
    ++result->iterations;
    if (MaxAbs(delta_) < tolerance_) break;
    // The model's decrease is what this step still buys: below the fraction, iterating
    // again only moves weakly constrained directions (delta is kept either way). Only if
    // the step did not raise chi2: a converged map's first step can (M3500's final batch
    // step: predicted 0.28, chi2 +0.06, a step of 0.8 rad), and the model is not to be
    // trusted there.
    const bool last = it + 1 >= max_iterations;
    const bool decrease_small = predicted_decrease < options_.convergence_decrease * chi2;
    if (KeepsEstimate()) {
      if (ShortenInTheCorrection(included, chi2, predicted_decrease, last)) break;
      continue;
    }
    if (!last || decrease_small) {
      // The chi2 at the step, evaluated once for both decisions.
      const double step_chi2 = Chi2Of(included, delta_);
      if (decrease_small && step_chi2 <= chi2) break;
      if (!last) ShortenOvershootingStep(included, chi2, predicted_decrease, step_chi2);
    }
  }
  stats_.iterations_to_convergence += result->iterations;
}

bool Smoother::Impl::ShortenInTheCorrection(const std::vector<int64_t>& included, double chi2,
                                            double predicted_decrease, bool last) {
  // Kept-estimate mode: delta stays R's solution, and the correction holds what the
  // estimate does not take of it. A fill batch step relinearises once, and its one step
  // was taken whole: at 100 robots a weakly held anchor's step of metres raised chi2 by
  // 10^3-10^5 (seed 3: 15831 -> 87955) for the correction to repair, or to stall on. Such a
  // step is halved here too, on the last iteration as well. A converging step whose
  // halved step buys less than the correction's tolerance has nothing left to give:
  // iterating again meets the same weak direction (the 100 x 180 run's final batch step:
  // 50 iterations at a predicted decrease of 0.5-0.7 in 2.2e4, each step raising chi2: 7-10 s).
  const double step_chi2 = Chi2Of(included, delta_);
  const bool decrease_small = predicted_decrease < options_.convergence_decrease * chi2;
  if (decrease_small && step_chi2 <= chi2) return true;
  // A rise within chi2's round-off (a sum of many terms) is no overshoot: near the optimum
  // the steps are noise and the last one is kept whole, as in the default mode.
  const double round_off = 1e-12 * chi2;
  if (!(step_chi2 > chi2 + predicted_decrease + round_off)) return false;
  double scaled_chi2 = step_chi2;
  const double scale = ScaleThatDoesNotRaiseChi2(included, chi2, &scaled_chi2);
  const bool exhausted = chi2 - scaled_chi2 < options_.correction_tolerance * chi2;
  if (last || exhausted) {
    for (int p = 0; p < static_cast<int>(delta_.size()); ++p)
      correction_[position_to_var_[p]] = (scale - 1.0) * delta_[p];
    return true;
  }
  for (Eigen::Vector3d& d : delta_) d *= scale;  // the next iteration relinearises there
  return false;
}

void Smoother::Impl::ShortenOvershootingStep(const std::vector<int64_t>& included, double chi2,
                                             double predicted_decrease, double step_chi2) {
  // A full Gauss-Newton step far from the optimum can raise chi2 by orders of magnitude,
  // and the next linearisation there is worse (the 20 x 300 simulation's final batch step:
  // chi2 1.6e6 -> 9.4e7 -> 1.9e11, 50 iterations, ending at 7.8e7). Only a step that
  // raised chi2 by more than it predicted to lower it is halved, until chi2 does not
  // rise: near the optimum the model holds and the steps stay full (M3500's first final
  // step: predicted 0.28, raised 0.06). The last iteration's delta stays R's solution.
  if (!(step_chi2 > chi2 + predicted_decrease)) return;
  const double scale = ScaleThatDoesNotRaiseChi2(included, chi2, &step_chi2);
  for (Eigen::Vector3d& d : delta_) d *= scale;  // a power of two: the halved values exactly
}

double Smoother::Impl::ScaleThatDoesNotRaiseChi2(const std::vector<int64_t>& included, double chi2,
                                                 double* step_chi2) {
  double scale = 1.0;
  std::vector<Eigen::Vector3d>& scaled = step_scratch_;
  scaled.resize(delta_.size());
  for (int k = 0; k < 20 && !(*step_chi2 <= chi2); ++k) {
    scale *= 0.5;
    for (size_t p = 0; p < delta_.size(); ++p) scaled[p] = scale * delta_[p];
    *step_chi2 = Chi2Of(included, scaled);
  }
  return scale;
}

void Smoother::Impl::DogLegIterations(const std::vector<int64_t>& included, int max_iterations,
                                      UpdateResult* result) {
  // Powell's dog-leg: blend the Gauss-Newton step with steepest descent inside a trust
  // region, accept a step only if chi2 decreases.
  double radius = options_.dogleg_initial_radius;
  double chi2 = Chi2Of(included, {});
  const int n = static_cast<int>(position_to_var_.size());
  for (int it = 0; it < max_iterations; ++it) {
    if (!FactorAll(included, result)) return;
    ++result->iterations;
    const std::vector<Eigen::Vector3d> gauss_newton = delta_;
    // Gradient direction g = J^T b (b = -whitened error) and |J g|^2.
    std::vector<Eigen::Vector3d> g(n, Eigen::Vector3d::Zero());
    std::vector<LinearizedFactor> lin(included.size());
    std::array<Pose2, kMaxFactorKeys> values;
    for (size_t k = 0; k < included.size(); ++k) {
      const FactorRecord& f = factors_[included[k]];
      for (int j = 0; j < f.num_vars; ++j) values[j] = vars_[f.vars[j]].linearization;
      lin[k] = Linearize(f.factor, values.data());
      for (int j = 0; j < f.num_vars; ++j) {
        g[vars_[f.vars[j]].position] -= lin[k].jacobians[j].transpose() * lin[k].whitened_error;
      }
    }
    auto apply_J = [&](const std::vector<Eigen::Vector3d>& h) {
      double norm2 = 0.0;
      for (size_t k = 0; k < included.size(); ++k) {
        const FactorRecord& f = factors_[included[k]];
        Eigen::Vector3d r = Eigen::Vector3d::Zero();
        for (int j = 0; j < f.num_vars; ++j)
          r += lin[k].jacobians[j] * h[vars_[f.vars[j]].position];
        norm2 += r.squaredNorm();
      }
      return norm2;
    };
    auto norm = [](const std::vector<Eigen::Vector3d>& v) {
      double s = 0.0;
      for (const auto& x : v) s += x.squaredNorm();
      return std::sqrt(s);
    };
    auto dot = [](const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b) {
      double s = 0.0;
      for (size_t i = 0; i < a.size(); ++i) s += a[i].dot(b[i]);
      return s;
    };
    const double g_norm = norm(g);
    const double Jg2 = apply_J(g);
    const double alpha = Jg2 > 0 ? g_norm * g_norm / Jg2 : 0.0;
    const double gn_norm = norm(gauss_newton);

    bool accepted = false;
    std::vector<Eigen::Vector3d> h(n);
    while (!accepted && radius > 1e-12) {
      if (gn_norm <= radius) {
        h = gauss_newton;
      } else if (alpha * g_norm >= radius) {
        for (int p = 0; p < n; ++p) h[p] = (radius / g_norm) * g[p];
      } else {
        // h = a + beta (b - a) with |h| = radius, a = alpha g, b = Gauss-Newton.
        std::vector<Eigen::Vector3d> a(n), ba(n);
        for (int p = 0; p < n; ++p) {
          a[p] = alpha * g[p];
          ba[p] = gauss_newton[p] - a[p];
        }
        const double aa = dot(a, a), ab = dot(a, ba), bb = dot(ba, ba);
        const double beta = (-ab + std::sqrt(ab * ab + bb * (radius * radius - aa))) / bb;
        for (int p = 0; p < n; ++p) h[p] = a[p] + beta * ba[p];
      }
      const double predicted = 2.0 * dot(g, h) - apply_J(h);
      const double new_chi2 = Chi2Of(included, h);
      const double rho = predicted > 0 ? (chi2 - new_chi2) / predicted : -1.0;
      if (rho > 0.75) {
        radius = std::max(radius, 3.0 * norm(h));
      } else if (rho < 0.25) {
        radius *= 0.5;
      }
      if (rho > 0 || (chi2 - new_chi2) >= 0.0) {
        accepted = true;
        for (int var : position_to_var_) {
          Variable& v = vars_[var];
          v.linearization = Retract(v.linearization, h[v.position]);
        }
        chi2 = new_chi2;
      }
    }
    if (!accepted || MaxAbs(h) < tolerance_) break;
  }
  stats_.iterations_to_convergence += result->iterations;
  // Leave R linearised at the final point, with its Gauss-Newton solution as delta.
  FactorAll(included, result);
}

}  // namespace anchormap
