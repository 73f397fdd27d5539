// Update() and its steps (smoother_impl.h).

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include <Eigen/Dense>

#include "common/solver/ordering.h"
#include "common/solver/smoother_impl.h"

namespace anchormap {

// --- Updates ---------------------------------------------------------------------------

std::vector<int64_t> Smoother::Impl::GroundPendingFactors(std::vector<char>* grounded) const {
  // A measurement enters R only when all but at most one of its variables are already
  // determined; it then determines the last one (every factor's Jacobian block is
  // invertible). Anything else waits, so R never gets a singular diagonal block.
  std::vector<int64_t> ready;
  std::vector<char> used(pending_factors_.size(), 0);
  bool progress = true;
  while (progress) {
    progress = false;
    for (size_t k = 0; k < pending_factors_.size(); ++k) {
      if (used[k]) continue;
      const FactorRecord& f = factors_[pending_factors_[k]];
      if (!f.active) {
        used[k] = 1;
        continue;
      }
      int unknown = -1, unknowns = 0;
      for (int j = 0; j < f.num_vars; ++j) {
        if (!(*grounded)[f.vars[j]]) {
          unknown = f.vars[j];
          ++unknowns;
        }
      }
      if (unknowns > 1) continue;
      if (unknown >= 0) (*grounded)[unknown] = 1;
      used[k] = 1;
      ready.push_back(pending_factors_[k]);
      progress = true;
    }
  }
  return ready;
}

void Smoother::Impl::TakeOutOfPending(const std::vector<int64_t>& done) {
  // O(pending + done log done), not O(all factors): this runs after every update.
  std::vector<int64_t> sorted_done = done;
  std::sort(sorted_done.begin(), sorted_done.end());
  std::vector<int64_t> still;
  for (int64_t f : pending_factors_) {
    if (!std::binary_search(sorted_done.begin(), sorted_done.end(), f) && factors_[f].active) {
      still.push_back(f);
    }
  }
  pending_factors_.swap(still);
  std::vector<int> vars;
  for (int v : pending_vars_) {
    if (vars_[v].position < 0) vars.push_back(v);
  }
  pending_vars_.swap(vars);
}

std::vector<int64_t> Smoother::Impl::FactorsReadyForGivens(std::vector<char>* grounded) const {
  // grounded[v] == (v is in R), kept between updates so that an update costs what it
  // touches: only new and pending variables need a fresh look (a batch step clears it).
  const size_t known = grounded->size();
  grounded->resize(vars_.size());
  for (size_t v = known; v < vars_.size(); ++v) (*grounded)[v] = vars_[v].position >= 0;
  for (int v : pending_vars_) (*grounded)[v] = vars_[v].position >= 0;
  return GroundPendingFactors(grounded);
}

bool Smoother::Impl::IncrementalStep(bool solve, UpdateResult* result, int64_t max_fill,
                                     int64_t max_work) {
  std::vector<char>& grounded = grounded_;
  const std::vector<int64_t> ready = FactorsReadyForGivens(&grounded);

  SparseR& R = MutableR();
  const int first_new = R.size();
  const bool keep_estimate = solve && KeepsEstimate();
  int appended = 0;
  for (int v : pending_vars_) {
    if (!grounded[v]) continue;
    vars_[v].position = R.size() + appended++;
    position_to_var_.push_back(v);
  }
  R.Append(appended);
  delta_.resize(R.size(), Eigen::Vector3d::Zero());

  const double innovation_before = innovation_;
  std::vector<int> touched;
  std::array<Pose2, kMaxFactorKeys> values;
  std::vector<NewRows> new_rows;
  new_rows.reserve(ready.size());
  std::vector<LinearizedFactor> new_jacobians;  // keep_estimate: for placing new variables
  for (int64_t id : ready) {
    const FactorRecord& f = factors_[id];
    for (int j = 0; j < f.num_vars; ++j) values[j] = EstimateOf(f.vars[j]);
    // Linearised at the current estimate, expressed relative to the linearisation point
    // of R: J (x - theta) = -e(x_hat) + J delta.
    const LinearizedFactor lin = Linearize(f.factor, values.data());
    MarkInR(id, values);
    NewRows rows;
    rows.rhs = -lin.whitened_error;
    for (int j = 0; j < f.num_vars; ++j) {
      const int position = vars_[f.vars[j]].position;
      rows.blocks.emplace_back(position, lin.jacobians[j]);
      rows.rhs += lin.jacobians[j] * OffsetOf(f.vars[j]);
    }
    if (options_.correction_tolerance > 0 && !keep_estimate)
      innovation_ += lin.whitened_error.squaredNorm();
    if (keep_estimate) new_jacobians.push_back(lin);
    // A variable this factor determines is placed by R relative to its neighbours'
    // uncorrected estimates (see PlaceByNeighboursCorrection).
    if (options_.correction_tolerance > 0 && !keep_estimate) {
      PlaceByNeighboursCorrection(f, lin, first_new);
    }
    new_rows.push_back(std::move(rows));
  }
  // All at once: their paths up R share the rows near the root.
  double leftover = 0.0;
  if (!R.EliminateWithin(std::move(new_rows), max_fill, max_work, &touched, &leftover)) {
    // Past the budget: R is as it was; the rest of this step is taken back.
    for (int64_t id : ready) TakeOutOfR(id);
    for (int p = first_new; p < R.size(); ++p) {
      const int var = position_to_var_[p];
      vars_[var].position = -1;
      correction_[var] = Eigen::Vector3d::Zero();
    }
    position_to_var_.resize(first_new);
    R.Truncate(first_new);
    delta_.resize(first_new);
    innovation_ = innovation_before;
    return false;
  }
  TakeOutOfPending(ready);

  if (!solve) return true;
  if (keep_estimate) {
    // R only preconditions the correction and the old variables keep their estimate: R's
    // new solution for them would only be taken back by their correction, so delta stays
    // as it was (no longer R's solution; partial and batch steps solve again), and a
    // back-substitution through the rows a loop closure changed (the map) is saved.
    PlaceNewVariables(ready, new_jacobians, first_new);
  } else if (options_.backsubstitution_threshold == 0.0) {
    R.BackSubstitute(&delta_);
    result->rows_backsubstituted = R.size();
  } else {
    result->rows_backsubstituted =
        R.BackSubstitutePartial(touched, options_.backsubstitution_threshold, &delta_);
  }
  if (keep_estimate) {
    // The old variables kept their estimate, so the gradient changed by these factors'
    // J^T e only: the skip test (CorrectEstimate) bounds what they add.
    uncorrected_factors_.insert(uncorrected_factors_.end(), ready.begin(), ready.end());
  } else if (options_.correction_tolerance > 0) {
    // The new factors at the new estimate: with a zero error at entry R's solution of the
    // old variables is unchanged, so these tell whether the gradient changed (a new
    // variable placed by one factor may disagree with its others).
    for (int64_t id : ready) {
      const FactorRecord& f = factors_[id];
      for (int j = 0; j < f.num_vars; ++j) values[j] = EstimateOf(f.vars[j]);
      innovation_ += FactorChi2(f.factor, values.data());
    }
  }
  return true;
}

void Smoother::Impl::PlaceNewVariables(const std::vector<int64_t>& ready,
                                       const std::vector<LinearizedFactor>& jacobians,
                                       int first_new) {
  // Factors enter R in the order they ground their variables, so the first new factor on
  // a new variable is the one that determines it: every other variable of that factor is
  // old or placed already.
  const int n = r_->size();
  std::vector<int> determining(n - first_new, -1);  // by new position: index in `ready`
  std::vector<int> placing_order;                   // new positions, in grounding order
  int from = first_new;
  for (size_t k = 0; k < ready.size(); ++k) {
    const FactorRecord& f = factors_[ready[k]];
    for (int j = 0; j < f.num_vars; ++j) {
      const int slot = vars_[f.vars[j]].position - first_new;
      if (slot < 0 || determining[slot] >= 0) continue;
      determining[slot] = static_cast<int>(k);
      placing_order.push_back(slot);
      for (int i = 0; i < f.num_vars; ++i) from = std::min(from, vars_[f.vars[i]].position);
    }
  }
  // R's new solution there: rows near the end (a trajectory's newest pose is ordered
  // last), so this is a few rows, not the map.
  std::vector<Eigen::Vector3d>& solution = tail_solution_;
  r_->BackSubstituteTail(from, &solution);
  for (int slot : placing_order) {
    const FactorRecord& f = factors_[ready[determining[slot]]];
    const LinearizedFactor& lin = jacobians[determining[slot]];
    // The new variable at R's solution relative to its neighbours', moved with their
    // estimates' offset from that solution through the factor's Jacobians (the new ones
    // placed before it included).
    const int p = first_new + slot;
    const int var = position_to_var_[p];
    delta_[p] = solution[p];
    Eigen::Vector3d pushed = Eigen::Vector3d::Zero();
    int self = -1;
    for (int i = 0; i < f.num_vars; ++i) {
      const int q = vars_[f.vars[i]].position;
      if (q == p) {
        self = i;
      } else {
        pushed.noalias() += lin.jacobians[i] * (OffsetOf(f.vars[i]) - solution[q]);
      }
    }
    correction_[var] = -lin.jacobians[self].partialPivLu().solve(pushed);
  }
}

void Smoother::Impl::PlaceByNeighboursCorrection(const FactorRecord& f, const LinearizedFactor& lin,
                                                 int first_new) {
  // Give each new, uncorrected variable of the factor its neighbours' correction, so that
  // the factor's linear model holds at their corrected estimates.
  for (int j = 0; j < f.num_vars; ++j) {
    const int var = f.vars[j];
    if (vars_[var].position < first_new || !correction_[var].isZero(0.0)) continue;
    Eigen::Vector3d pushed = Eigen::Vector3d::Zero();
    for (int i = 0; i < f.num_vars; ++i) {
      if (i != j) pushed.noalias() += lin.jacobians[i] * correction_[f.vars[i]];
    }
    if (!pushed.isZero(0.0)) correction_[var] = -lin.jacobians[j].partialPivLu().solve(pushed);
  }
}

void Smoother::Impl::KeepEstimate(const std::vector<Pose2>& estimate) {
  for (int p = 0; p < static_cast<int>(position_to_var_.size()); ++p) {
    const int var = position_to_var_[p];
    correction_[var] = Difference(estimate[var], vars_[var].linearization) - delta_[p];
  }
}

bool Smoother::Impl::PartialRelinearization(const std::vector<int>& forced, bool full_solve,
                                            UpdateResult* result, bool keep_estimate,
                                            int max_rows) {
  const auto start = std::chrono::steady_clock::now();
  const int n = r_->size();
  // 1. The drifted variables S (by position) and their new linearisation points.
  std::vector<char> drifted(n, 0), in_b(n, 0);
  for (int p : forced) drifted[p] = 1;
  std::vector<int> drifted_positions;
  for (int p = 0; p < n; ++p) {
    if (drifted[p]) drifted_positions.push_back(p);
  }
  if (drifted_positions.empty()) return true;
  auto theta = [&](int var) {  // the new linearisation point
    const Variable& v = vars_[var];
    return drifted[v.position] ? Retract(v.linearization, OffsetOf(var)) : v.linearization;
  };
  auto usable = [&](int64_t f) { return factors_[f].active && factor_lin_[f].in_r; };
  // 2. Affected: S, every variable that shares a factor with S (those factors are
  // relinearised), the anchors and the latest poses kept last (KeepsLatestPoseLast; at the
  // end for the next Givens updates), then every ancestor in the elimination tree, so that no row
  // of B references a row outside it.
  for (int p : drifted_positions) {
    in_b[p] = 1;
    for (int64_t f : var_factors_[position_to_var_[p]]) {
      if (!usable(f)) continue;
      for (int j = 0; j < factors_[f].num_vars; ++j) in_b[vars_[factors_[f].vars[j]].position] = 1;
    }
  }
  auto is_keep_last = [&](int var) {
    const Key& key = vars_[var].key;
    if (key.is_anchor()) return true;
    auto it = trajectories_.find(key.trajectory);
    return it != trajectories_.end() && it->second.max_index == key.index &&
           KeepsLatestPoseLast(key.trajectory);
  };
  for (const auto& [t, info] : trajectories_) {
    for (const Key& key : {Key(PoseKey{t, info.max_index}), Key(AnchorKey{t})}) {
      if (!key.is_anchor() && !KeepsLatestPoseLast(t)) continue;
      auto it = index_.find(key);
      if (it != index_.end() && vars_[it->second].position >= 0) {
        in_b[vars_[it->second].position] = 1;
      }
    }
  }
  // (Every block of row p is an ancestor of p; marking them all, not only the parent,
  // keeps B closed even where an exact zero dropped a fill-in block.)
  const int64_t marked_before_closure = std::count(in_b.begin(), in_b.end(), 1);
  int p0 = n;
  for (int p = 0; p < n; ++p) {
    if (!in_b[p]) continue;
    p0 = std::min(p0, p);
    for (const auto& entry : r_->row(p).right) in_b[entry.first] = 1;
  }
  std::vector<int> b_positions, kept;  // B ascending; the tail's other rows
  std::vector<int> local(n - p0, -1);  // old position -> index in B
  for (int p = p0; p < n; ++p) {
    if (in_b[p]) {
      local[p - p0] = static_cast<int>(b_positions.size());
      b_positions.push_back(p);
    } else {
      kept.push_back(p);
    }
  }
  const int nb = static_cast<int>(b_positions.size());
  if (nb > max_rows) return false;

  // 3. Factors with a variable in B (relinearised if they touch S), and the rows outside
  // B that reference B (their part in B is subtracted: R_BB^T R_BB = H_BB - R_FB^T R_FB).
  if (factor_stamp_.size() < factors_.size()) factor_stamp_.resize(factors_.size(), 0);
  ++stamp_;
  struct LocalFactor {
    int64_t id;
    bool relinearize;
  };
  std::vector<LocalFactor> local_factors;
  std::vector<int64_t> leaving;  // in R but no longer active (a merge's dropped gauge prior)
  for (int p : b_positions) {
    for (int64_t f : var_factors_[position_to_var_[p]]) {
      if (factor_stamp_[f] == stamp_) continue;
      factor_stamp_[f] = stamp_;
      if (!factors_[f].active && factor_lin_[f].in_r) leaving.push_back(f);
      if (!usable(f)) continue;
      bool touches_s = false;
      for (int j = 0; j < factors_[f].num_vars; ++j) {
        touches_s = touches_s || drifted[vars_[factors_[f].vars[j]].position];
      }
      local_factors.push_back({f, touches_s});
    }
  }
  std::vector<int> boundary;  // rows outside B with a block in B
  {
    std::vector<char> seen(n, 0);
    for (int p : b_positions) {
      for (int r : r_->RowsReferencing(p)) {
        if (!in_b[r] && !seen[r]) {
          seen[r] = 1;
          boundary.push_back(r);
        }
      }
    }
  }
  // Their right-hand sides in the new coordinates: d_r - sum over S of R_rq (theta'_q - theta_q).
  std::vector<std::pair<int, Eigen::Vector3d>> boundary_rhs;
  boundary_rhs.reserve(boundary.size());
  for (int r : boundary) {
    Eigen::Vector3d d = r_->row(r).rhs;
    for (const auto& [q, block] : r_->row(r).right) {
      if (drifted[q]) d.noalias() -= block * OffsetOf(position_to_var_[q]);
    }
    boundary_rhs.emplace_back(r, d);
  }

  // 4. Local ordering of B (CCOLAMD, the same constraints as a batch step).
  std::vector<int> structure_start(1, 0), structure;
  structure_start.reserve(local_factors.size() + boundary.size() + 1);
  for (const LocalFactor& lf : local_factors) {
    for (int j = 0; j < factors_[lf.id].num_vars; ++j) {
      const int p = vars_[factors_[lf.id].vars[j]].position;
      if (in_b[p]) structure.push_back(local[p - p0]);
    }
    structure_start.push_back(static_cast<int>(structure.size()));
  }
  for (int r : boundary) {
    for (const auto& [q, block] : r_->row(r).right) {
      if (q >= p0 && in_b[q]) structure.push_back(local[q - p0]);
    }
    structure_start.push_back(static_cast<int>(structure.size()));
  }
  std::vector<bool> keep_last(nb);
  for (int k = 0; k < nb; ++k) keep_last[k] = is_keep_last(position_to_var_[b_positions[k]]);
  Result<std::vector<int>> ordering = ComputeOrdering(nb, structure_start, structure, keep_last);
  if (!ordering.ok()) {
    result->status = ordering.status();
    return false;
  }
  std::vector<int> order_of(nb);  // B index -> new local position
  for (int k = 0; k < nb; ++k) order_of[(*ordering)[k]] = k;

  // 5. Normal equations of B in the new order, minus the boundary rows' part; factor.
  // Blocks are gathered in one flat list and grouped by column once (a vector per column
  // cost more in allocations than the arithmetic).
  struct Entry {
    int row, column;
    Eigen::Matrix3d block;
  };
  std::vector<Entry> entries;
  entries.reserve(4 * local_factors.size() + 8 * boundary.size());
  std::vector<Eigen::Vector3d> gradient(nb, Eigen::Vector3d::Zero());
  auto add_row_block = [&](int a, int b, const Eigen::Matrix3d& block) {  // H_ab, a <= b
    entries.push_back({a, b, block});
  };
  std::vector<std::array<Pose2, kMaxFactorKeys>> relinearized_at;
  std::array<Pose2, kMaxFactorKeys> at;
  std::array<int, kMaxFactorKeys> slot;
  for (const LocalFactor& lf : local_factors) {
    const FactorRecord& f = factors_[lf.id];
    if (lf.relinearize) {
      for (int j = 0; j < f.num_vars; ++j) at[j] = theta(f.vars[j]);
      relinearized_at.push_back(at);
    } else {
      at = factor_lin_[lf.id].at;
    }
    const LinearizedFactor lin = Linearize(f.factor, at.data());
    Eigen::Vector3d rhs = -lin.whitened_error;
    for (int j = 0; j < f.num_vars; ++j) {
      const Pose2 point = theta(f.vars[j]);
      const Eigen::Vector3d offset(at[j].x() - point.x(), at[j].y() - point.y(),
                                   std::remainder(at[j].theta() - point.theta(), 2.0 * M_PI));
      rhs.noalias() += lin.jacobians[j] * offset;
      const int p = vars_[f.vars[j]].position;
      slot[j] = in_b[p] ? order_of[local[p - p0]] : -1;
    }
    for (int a = 0; a < f.num_vars; ++a) {
      if (slot[a] < 0) continue;
      gradient[slot[a]].noalias() += lin.jacobians[a].transpose() * rhs;
      for (int b = 0; b < f.num_vars; ++b) {
        if (slot[b] < 0 || slot[a] > slot[b] || (slot[a] == slot[b] && a > b)) continue;
        Eigen::Matrix3d block = lin.jacobians[a].transpose() * lin.jacobians[b];
        if (slot[a] == slot[b] && a != b) block += block.transpose().eval();
        add_row_block(slot[a], slot[b], block);
      }
    }
  }
  std::vector<std::pair<int, const Eigen::Matrix3d*>> part;
  for (size_t k = 0; k < boundary.size(); ++k) {
    const RBlockRow& row = r_->row(boundary[k]);
    part.clear();
    for (const auto& [q, block] : row.right) {
      if (q >= p0 && in_b[q]) part.emplace_back(order_of[local[q - p0]], &block);
    }
    for (const auto& [a, block_a] : part) {
      gradient[a].noalias() -= block_a->transpose() * boundary_rhs[k].second;
      for (const auto& [b, block_b] : part) {
        if (a > b) continue;
        add_row_block(a, b, -(block_a->transpose() * *block_b));
      }
    }
  }
  std::vector<int> column_start(nb + 1, 0);
  for (const Entry& entry : entries) ++column_start[entry.column + 1];
  for (int q = 0; q < nb; ++q) column_start[q + 1] += column_start[q];
  std::vector<std::pair<int, Eigen::Matrix3d>> blocks(entries.size());
  {
    std::vector<int> next(column_start.begin(), column_start.end() - 1);
    for (const Entry& entry : entries) blocks[next[entry.column]++] = {entry.row, entry.block};
  }
  std::vector<RBlockRow> rows;
  std::string error;
  if (!batch_.FactorBlocks(nb, column_start, std::move(blocks), std::move(gradient), &rows,
                           &error)) {
    result->status = Status::Error(ErrorCode::kNumericalFailure, error);
    return false;
  }

  // 6. Commit (nothing fails from here): linearisation points, factor records, R, positions.
  std::vector<Pose2> estimate;
  if (keep_estimate) {
    estimate.reserve(vars_.size());
    for (int var = 0; var < static_cast<int>(vars_.size()); ++var)
      estimate.push_back(EstimateOf(var));
  }
  const int first_b = p0 + static_cast<int>(kept.size());
  std::vector<int> new_position(n - p0);
  for (size_t k = 0; k < kept.size(); ++k) new_position[kept[k] - p0] = p0 + static_cast<int>(k);
  for (int k = 0; k < nb; ++k) new_position[b_positions[k] - p0] = first_b + order_of[k];
  for (RBlockRow& row : rows) {
    for (auto& entry : row.right) entry.first += first_b;
  }
  size_t next_relinearized = 0;
  for (const LocalFactor& lf : local_factors) {
    if (lf.relinearize) MarkInR(lf.id, relinearized_at[next_relinearized++]);
  }
  for (int64_t f : leaving) TakeOutOfR(f);
  std::vector<Eigen::Vector3d> old_delta(delta_.begin() + p0, delta_.end());
  for (int p : drifted_positions) {
    Variable& v = vars_[position_to_var_[p]];
    v.linearization = Retract(v.linearization, OffsetOf(position_to_var_[p]));
    correction_[position_to_var_[p]].setZero();
  }
  // The corrections compensated the old rows' linearisation error, which this step has
  // (in part) removed: start the next correction from R's solution.
  for (Eigen::Vector3d& c : correction_) c.setZero();
  for (int p : drifted_positions) {
    old_delta[p - p0] = Eigen::Vector3d::Zero();
    delta_[p].setZero();
  }
  MutableR().ReplaceTail(p0, new_position, kept, std::move(rows), boundary_rhs);
  std::vector<int> old_vars(position_to_var_.begin() + p0, position_to_var_.end());
  for (int k = 0; k < n - p0; ++k) {
    const int p = new_position[k];
    position_to_var_[p] = old_vars[k];
    vars_[old_vars[k]].position = p;
    delta_[p] = old_delta[k];
  }
  if (full_solve || options_.backsubstitution_threshold == 0.0) {
    r_->BackSubstitute(&delta_);
    result->rows_backsubstituted += r_->size();
  } else {
    std::vector<int> dirty;
    for (int p = p0; p < n; ++p) dirty.push_back(p);
    for (int r : boundary) dirty.push_back(r < p0 ? r : new_position[r - p0]);
    result->rows_backsubstituted +=
        MutableR().BackSubstitutePartial(dirty, options_.backsubstitution_threshold, &delta_);
  }
  if (keep_estimate) KeepEstimate(estimate);
  correction_converged_ = false;
  ++stats_.partial_relinearizations;
  stats_.relinearized_variables += static_cast<int64_t>(drifted_positions.size());
  stats_.rows_reeliminated += nb;
  stats_.rows_before_closure += marked_before_closure;
  stats_.rows_in_tails += n - p0;
  stats_.partial_seconds += Seconds(start);
  result->relinearized = static_cast<int>(drifted_positions.size());
  return true;
}

std::vector<int> Smoother::Impl::DriftedPositions(double* max_drift) const {
  std::vector<int> positions;
  *max_drift = 0.0;
  for (int p = 0; p < static_cast<int>(delta_.size()); ++p) {
    const double drift = Drift(delta_[p] + correction_[position_to_var_[p]]);
    *max_drift = std::max(*max_drift, drift);
    if (drift > options_.relinearize_threshold) positions.push_back(p);
  }
  return positions;
}

void Smoother::Impl::PartialMergeStep(UpdateResult* result) {
  result->groups_merged = 1;
  correction_converged_ = false;  // anchors moved: the gradient changed
  // Givens updates first, so that the encounter that joins the groups is in R before the
  // absorbed group's gauge prior leaves it; no solve yet: delta holds the moved anchors.
  IncrementalStep(/*solve=*/false, result);
  std::vector<int> forced;
  for (int var : merge_vars_) {
    if (vars_[var].position >= 0) forced.push_back(vars_[var].position);
  }
  std::sort(forced.begin(), forced.end());
  forced.erase(std::unique(forced.begin(), forced.end()), forced.end());
  if (forced.empty()) {
    r_->BackSubstitute(&delta_);
    result->rows_backsubstituted += r_->size();
    ++stats_.partial_merges;
  } else if (PartialRelinearization(forced, /*full_solve=*/true, result)) {
    ++stats_.partial_merges;
  } else {
    // The state is the Givens-updated one with the anchors moved: a batch step from it.
    ++stats_.batch_steps_on_merge;
    result->status = Status::Ok();
    BatchStep(/*converge=*/true, options_.convergence_step, result);
    if (!result->status.ok()) return;  // merge_pending_ stays: the next update retries
  }
  merge_vars_.clear();
  merge_pending_ = false;
  // A merge moves estimates by more than an ordinary update: relinearise what drifted
  // now, so that the published estimate is near the optimum after this update too.
  for (int k = 0; k < 3 && options_.relinearize_threshold > 0; ++k) {
    double max_drift = 0.0;
    const std::vector<int> drifted = DriftedPositions(&max_drift);
    if (drifted.empty()) break;
    if (!PartialRelinearization(drifted, /*full_solve=*/false, result)) {
      result->status = Status::Ok();  // the state is valid without it; drift is re-checked
      break;
    }
  }
}

bool Smoother::Impl::FactorAll(const std::vector<int64_t>& included, UpdateResult* result,
                               double* chi2, double* predicted_decrease) {
  std::vector<LinearizedFactor> linearized(included.size());
  std::vector<PositionedFactor> positioned(included.size());
  std::array<Pose2, kMaxFactorKeys> values;
  for (size_t k = 0; k < included.size(); ++k) {
    const FactorRecord& f = factors_[included[k]];
    for (int j = 0; j < f.num_vars; ++j) values[j] = vars_[f.vars[j]].linearization;
    linearized[k] = Linearize(f.factor, values.data());
    MarkInR(included[k], values);
    positioned[k].num_keys = f.num_vars;
    for (int j = 0; j < f.num_vars; ++j) positioned[k].positions[j] = vars_[f.vars[j]].position;
    positioned[k].jacobians = linearized[k].jacobians.data();
    positioned[k].rhs = -linearized[k].whitened_error;
  }
  std::vector<RBlockRow> rows;
  std::string error;
  if (!batch_.Factor(static_cast<int>(position_to_var_.size()), positioned, &rows, &error)) {
    result->status = Status::Error(error);
    return false;
  }
  if (chi2) {
    *chi2 = 0.0;
    for (const LinearizedFactor& l : linearized) *chi2 += l.whitened_error.squaredNorm();
  }
  if (predicted_decrease) {
    *predicted_decrease = 0.0;
    for (const RBlockRow& row : rows) *predicted_decrease += row.rhs.squaredNorm();
  }
  FreshR().Assign(std::move(rows));
  r_->BackSubstitute(&delta_);
  return true;
}

void Smoother::Impl::BatchStep(bool converge, double tolerance, UpdateResult* result) {
  const auto start = std::chrono::steady_clock::now();
  const int iterations_before = result->iterations;
  tolerance_ = tolerance;
  Snapshot before = Save();
  auto fail = [&](Status status) {
    Restore(std::move(before));
    result->status = std::move(status);
    result->iterations = iterations_before;
    stats_.batch_seconds += Seconds(start);
    ++stats_.failed_batch_steps;
  };
  result->batch_step = true;
  // Relinearise everything at the current estimate.
  for (size_t var = 0; var < vars_.size(); ++var) {
    Variable& v = vars_[var];
    if (v.position >= 0)
      v.linearization = Retract(v.linearization, OffsetOf(static_cast<int>(var)));
    correction_[var].setZero();
  }
  // Start from scratch: every active factor is pending, grounding starts at the priors.
  for (size_t f = 0; f < factor_lin_.size(); ++f) TakeOutOfR(static_cast<int64_t>(f));
  pending_factors_.clear();
  for (size_t f = 0; f < factors_.size(); ++f) {
    if (factors_[f].active) pending_factors_.push_back(static_cast<int64_t>(f));
  }
  std::vector<char> grounded(vars_.size(), 0);
  const std::vector<int64_t> included = GroundPendingFactors(&grounded);

  // Ordering over the grounded variables; anchors (and each trajectory's latest pose) last.
  std::vector<int> dense(vars_.size(), -1), dense_to_var;
  for (size_t v = 0; v < vars_.size(); ++v) {
    if (grounded[v]) {
      dense[v] = static_cast<int>(dense_to_var.size());
      dense_to_var.push_back(static_cast<int>(v));
    }
  }
  std::vector<std::vector<int>> factor_vars(included.size());
  for (size_t k = 0; k < included.size(); ++k) {
    const FactorRecord& f = factors_[included[k]];
    for (int j = 0; j < f.num_vars; ++j) factor_vars[k].push_back(dense[f.vars[j]]);
  }
  std::unordered_map<TrajectoryId, std::pair<int32_t, int>> latest;  // trajectory -> (index, dense)
  std::vector<bool> keep_last(dense_to_var.size(), false);
  for (size_t d = 0; d < dense_to_var.size(); ++d) {
    const Key& key = vars_[dense_to_var[d]].key;
    if (key.is_anchor()) {
      keep_last[d] = true;
      continue;
    }
    auto [it, inserted] = latest.try_emplace(key.trajectory, key.index, static_cast<int>(d));
    if (!inserted && key.index > it->second.first) it->second = {key.index, static_cast<int>(d)};
  }
  for (const auto& [t, entry] : latest) {
    if (KeepsLatestPoseLast(t)) keep_last[entry.second] = true;
  }
  Result<std::vector<int>> ordering =
      ComputeOrdering(static_cast<int>(dense_to_var.size()), factor_vars, keep_last);
  if (!ordering.ok()) return fail(ordering.status());
  const std::vector<int>& order = *ordering;
  for (Variable& v : vars_) v.position = -1;
  grounded_.clear();
  position_to_var_.clear();
  for (int d : order) {
    vars_[dense_to_var[d]].position = static_cast<int>(position_to_var_.size());
    position_to_var_.push_back(dense_to_var[d]);
  }
  delta_.assign(position_to_var_.size(), Eigen::Vector3d::Zero());
  TakeOutOfPending(included);
  // Every variable this step left out of R waits again, those that were in R before
  // included (their factors no longer ground them, e.g. after a merge): the Givens update
  // that grounds one gives it a position. Left out of pending_vars_, it would be grounded
  // with no position and its factor's rows would index R at -1.
  pending_vars_.clear();
  for (size_t v = 0; v < vars_.size(); ++v) {
    if (vars_[v].position < 0) pending_vars_.push_back(static_cast<int>(v));
  }

  const int max_iterations = converge ? options_.max_batch_iterations : 1;
  if (options_.method == NonlinearMethod::kDogLeg) {
    DogLegIterations(included, max_iterations, result);
  } else {
    GaussNewtonIterations(included, max_iterations, result);
  }
  if (!result->status.ok()) return fail(result->status);
  nonzeros_after_batch_ = r_->NonZeros();
  updates_since_batch_ = 0;
  correction_converged_ = false;
  stats_.batch_seconds += Seconds(start);
  ++stats_.batch_steps;
  stats_.batch_iterations += result->iterations - iterations_before;
}

UpdateResult Smoother::Impl::Update(bool force_batch, double convergence_step) {
  const auto start = std::chrono::steady_clock::now();
  UpdateResult result;
  result.update = ++stats_.updates;
  covariances_.reset();
  const int anchors_before = CountAnchors();
  const int waiting_before = ActivePending();

  // 1. The kind of step, from the statistics (batch_policy.h).
  ++updates_since_batch_;
  StepKind kind = ChooseStep(options_, {force_batch, merge_pending_, updates_since_batch_,
                                        r_->NonZeros(), nonzeros_after_batch_});
  if (kind == StepKind::kIncremental &&
      !IncrementalStep(/*solve=*/true, &result, GivensFillBudget(), GivensWorkBudget())) {
    // The Givens updates would fill R, or take work, more than a batch step costs (with
    // the fill the next update would reorder anyway): nothing changed, a batch step (a
    // fresh ordering) takes the factors.
    kind = StepKind::kBatchOnFill;
  }
  if (kind == StepKind::kBatchOnMerge && MergesByPartialStep()) {
    // 2a. Groups joined: a partial step over the anchors (relative formulation).
    PartialMergeStep(&result);
    if (result.status.ok() && options_.correction_tolerance > 0 && !CorrectEstimate() &&
        options_.relinearize_when_correction_stalls) {
      RelinearizeUntilCorrected(&result);
    }
    stats_.incremental_seconds += Seconds(start);
  } else if (kind != StepKind::kIncremental) {
    // 2b. A batch step: relinearise, reorder, refactor.
    CountBatchStep(kind, &result);
    BatchStep(IteratesToConvergence(kind, options_),
              convergence_step > 0 ? convergence_step : options_.convergence_step, &result);
    if (result.status.ok()) {
      merge_pending_ = false;  // else the next update tries again
      merge_vars_.clear();
    }
    // A periodic step relinearises once: one Gauss-Newton step from the estimate with this
    // update's new factors in it, which can leave it farther from the optimum than the
    // correction would (a loop closure); with R fresh the correction converges at once.
    if (result.status.ok() && options_.correction_tolerance > 0 &&
        !IteratesToConvergence(kind, options_) && !CorrectEstimate() &&
        options_.relinearize_when_correction_stalls) {
      RelinearizeUntilCorrected(&result);
    }
  } else {
    // 2c. Givens updates (done above), then relinearisation where estimates drifted.
    stats_.incremental_seconds += Seconds(start);
    if (nonzeros_after_batch_ == 0 && options_.relinearize_when_correction_stalls) {
      // Few partial steps reorder R in this mode: batch on fill from the first update on
      // (4x growth: a number of batch steps that grows with the log of the map's size).
      nonzeros_after_batch_ = r_->NonZeros();
    }
    const bool correcting = options_.correction_tolerance > 0 && result.status.ok();
    const bool on_stall = correcting && options_.relinearize_when_correction_stalls;
    const bool check_due = DriftCheckDue(options_, ++updates_since_drift_check_);
    if (on_stall) {
      if (!CorrectEstimate()) RelinearizeUntilCorrected(&result);
    } else {
      if (result.status.ok() && check_due) {
        updates_since_drift_check_ = 0;
        RelinearizeDrifted(&result);
      }
      if (correcting && result.status.ok()) CorrectEstimate();
    }
  }
  // 3. What is left waiting, and the counters.
  if (!pending_vars_.empty() && result.status.ok()) {
    result.status = Status::Error(std::to_string(pending_vars_.size()) +
                                  " variable(s) wait for measurements that determine them, e.g. " +
                                  vars_[pending_vars_.front()].key.ToString());
  }
  result.factors_added = waiting_before - ActivePending();  // waiting factors now in R
  result.anchors_created = CountAnchors() - anchors_before;
  stats_.rows_backsubstituted += result.rows_backsubstituted;
  stats_.nnz_r = r_->NonZeros();
  stats_.givens_block_rows = r_->eliminated_block_rows();
  stats_.givens_block_columns = r_->eliminated_block_columns();
  result.seconds = Seconds(start);
  return result;
}

void Smoother::Impl::RelinearizeUntilCorrected(UpdateResult* result) {
  // R was too stale to converge: relinearise what drifted and correct again (a fresher R
  // is a better preconditioner), at most three times, as after a merge. A partial step
  // that would re-eliminate more than half of R is a batch step instead (about the same
  // work, every row at one point, R reordered), unless this update took one already, and
  // after it nothing is relinearised again in this update: a correction that still stalls
  // then stalls on the problem's nonlinearity (a large closure bending the map), which
  // relinearising again only chases.
  for (int k = 0; k < 3 && result->status.ok(); ++k) {
    const bool batch_before = result->batch_step;
    const int max_partial_rows = batch_before ? std::numeric_limits<int>::max() : r_->size() / 2;
    if (!RelinearizeDrifted(result, max_partial_rows) || !result->status.ok()) return;
    if (CorrectEstimate() || result->batch_step != batch_before) return;
  }
}

bool Smoother::Impl::RelinearizeDrifted(UpdateResult* result, int max_partial_rows) {
  double max_drift = 0.0;
  const std::vector<int> drifted = DriftedPositions(&max_drift);
  if (drifted.empty()) return false;
  switch (OnDrift(options_, max_drift)) {
    case DriftAction::kNone:
      break;
    case DriftAction::kPartialRelinearization:
      if (!PartialRelinearization(drifted, /*full_solve=*/false, result, KeepsEstimate(),
                                  max_partial_rows) &&
          result->status.ok()) {
        ++stats_.batch_steps_on_drift;
        BatchStep(options_.converge_periodic_batches, options_.convergence_step, result);
      }
      break;
    case DriftAction::kBatchStep:
      ++stats_.batch_steps_on_drift;
      BatchStep(options_.converge_periodic_batches, options_.convergence_step, result);
      break;
  }
  return true;
}

void Smoother::Impl::CountBatchStep(StepKind kind, UpdateResult* result) {
  if (merge_pending_) kind = StepKind::kBatchOnMerge;  // also when forced meanwhile
  switch (kind) {
    case StepKind::kBatchOnMerge:
      ++stats_.batch_steps_on_merge;
      result->groups_merged = 1;
      break;
    case StepKind::kBatchOnClock:
      ++stats_.batch_steps_on_clock;
      break;
    case StepKind::kBatchOnFill:
      ++stats_.batch_steps_on_fill;
      break;
    case StepKind::kBatchForced:
    case StepKind::kIncremental:
      break;
  }
}

}  // namespace anchormap
