// Smoother::ExportState / ImportState (smoother_state.h): the incremental state as plain
// values, and back.

#include "common/solver/smoother_state.h"

#include <string>
#include <utility>
#include <vector>

#include "common/solver/smoother_impl.h"

namespace anchormap {

SmootherState Smoother::Impl::ExportState() const {
  SmootherState s;
  s.variables.reserve(vars_.size());
  for (const Variable& v : vars_) s.variables.push_back({v.linearization, v.position});
  s.factors.reserve(factors_.size());
  for (size_t f = 0; f < factors_.size(); ++f) {
    s.factors.push_back({factors_[f].active, factor_lin_[f].in_r, factor_lin_[f].at});
  }
  s.pending_factors = pending_factors_;
  s.pending_variables = pending_vars_;
  s.grounded.assign(grounded_.begin(), grounded_.end());
  s.position_to_variable = position_to_var_;
  s.delta = delta_;
  s.correction = correction_;
  s.correction_converged = correction_converged_;
  s.last_chi2 = last_chi2_;
  s.innovation = innovation_;
  s.uncorrected_factors = uncorrected_factors_;
  s.local_pass_values.reserve(pass_values_.size());
  for (const auto& [var, value] : pass_values_) s.local_pass_values.push_back({var, value});
  s.local_moved_factors = moved_factors_;
  s.local_seeds_from = static_cast<int64_t>(local_seeds_from_);
  s.r = r_->ExportState();
  s.merge_pending = merge_pending_;
  s.merge_variables = merge_vars_;
  s.tolerance = tolerance_;
  s.updates_since_batch = updates_since_batch_;
  s.updates_since_drift_check = updates_since_drift_check_;
  s.nonzeros_after_batch = nonzeros_after_batch_;
  s.stats = stats_;
  return s;
}

Status Smoother::Impl::ImportState(SmootherState s) {
  auto refuse = [](const std::string& why) {
    return Status::Error(ErrorCode::kInvalidArgument, "smoother state refused: " + why);
  };
  const int num_vars = static_cast<int>(vars_.size());
  const int64_t num_factors = static_cast<int64_t>(factors_.size());
  if (s.variables.size() != vars_.size()) return refuse("another number of variables");
  if (s.factors.size() != factors_.size()) return refuse("another number of factors");
  if (s.correction.size() != vars_.size()) return refuse("corrections");
  if (s.grounded.size() > vars_.size()) return refuse("grounded");
  const int num_positions = static_cast<int>(s.position_to_variable.size());
  if (s.delta.size() != s.position_to_variable.size() ||
      s.r.rows.size() != s.position_to_variable.size()) {
    return refuse("positions, delta and R disagree");
  }
  for (int p = 0; p < num_positions; ++p) {
    const int var = s.position_to_variable[p];
    if (var < 0 || var >= num_vars || s.variables[var].position != p) {
      return refuse("position " + std::to_string(p));
    }
  }
  for (size_t f = 0; f < factors_.size(); ++f) {
    if (s.factors[f].active != factors_[f].active) return refuse("factor " + std::to_string(f));
  }
  for (int64_t f : s.pending_factors) {
    if (f < 0 || f >= num_factors) return refuse("pending factor");
  }
  for (int64_t f : s.uncorrected_factors) {
    if (f < 0 || f >= num_factors) return refuse("uncorrected factor");
  }
  if (s.local_seeds_from < 0 ||
      s.local_seeds_from > static_cast<int64_t>(s.uncorrected_factors.size())) {
    return refuse("local seeds");
  }
  for (size_t k = 0; k < s.local_moved_factors.size(); ++k) {
    const int64_t f = s.local_moved_factors[k];
    if (f < 0 || f >= num_factors || (k > 0 && f <= s.local_moved_factors[k - 1])) {
      return refuse("locally moved factor");
    }
  }
  {
    std::vector<char> seen(vars_.size(), 0);
    for (const SmootherState::PassValue& p : s.local_pass_values) {
      if (p.variable < 0 || p.variable >= num_vars || seen[p.variable]) {
        return refuse("local pass value");
      }
      seen[p.variable] = 1;
    }
  }
  for (int var : s.pending_variables) {
    if (var < 0 || var >= num_vars) return refuse("pending variable");
  }
  for (int var : s.merge_variables) {
    if (var < 0 || var >= num_vars) return refuse("merge variable");
  }
  for (int var = 0; var < num_vars; ++var) {
    const int position = s.variables[var].position;
    if (position < -1 || position >= num_positions) return refuse("variable position");
  }
  auto r = std::make_shared<SparseR>();
  if (!r->ImportState(std::move(s.r))) return refuse("R");

  for (int var = 0; var < num_vars; ++var) {
    vars_[var].linearization = s.variables[var].linearization;
    vars_[var].position = s.variables[var].position;
  }
  for (size_t f = 0; f < factors_.size(); ++f) {
    factor_lin_[f].in_r = s.factors[f].in_r;
    factor_lin_[f].at = s.factors[f].at;
  }
  pending_factors_ = std::move(s.pending_factors);
  pending_vars_ = std::move(s.pending_variables);
  grounded_.assign(s.grounded.begin(), s.grounded.end());
  position_to_var_ = std::move(s.position_to_variable);
  delta_ = std::move(s.delta);
  correction_ = std::move(s.correction);
  correction_converged_ = s.correction_converged;
  last_chi2_ = s.last_chi2;
  innovation_ = s.innovation;
  uncorrected_factors_ = std::move(s.uncorrected_factors);
  pass_values_.clear();
  pass_index_.assign(vars_.size(), -1);
  for (const SmootherState::PassValue& p : s.local_pass_values) {
    pass_index_[p.variable] = static_cast<int>(pass_values_.size());
    pass_values_.emplace_back(p.variable, p.value);
  }
  moved_factors_ = std::move(s.local_moved_factors);
  local_seeds_from_ = static_cast<size_t>(s.local_seeds_from);
  RecountFactorsInR();
  gradient_.Clear();  // a function of the estimate: rebuilt by the next pass
  r_ = std::move(r);
  covariances_.reset();
  // Work space only: a partial step compares stamps with a fresh one.
  factor_stamp_.clear();
  stamp_ = 0;
  merge_pending_ = s.merge_pending;
  merge_vars_ = std::move(s.merge_variables);
  tolerance_ = s.tolerance;
  updates_since_batch_ = s.updates_since_batch;
  updates_since_drift_check_ = s.updates_since_drift_check;
  nonzeros_after_batch_ = s.nonzeros_after_batch;
  stats_ = s.stats;
  return Status::Ok();
}

}  // namespace anchormap
