#include "server/smoother_state_codec.h"

#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

namespace anchormap {
namespace {

void PutVector3(ByteWriter* w, const Eigen::Vector3d& v) {
  for (int i = 0; i < 3; ++i) w->F64(v(i));
}
Eigen::Vector3d GetVector3(ByteReader* r) {
  Eigen::Vector3d v;
  for (int i = 0; i < 3; ++i) v(i) = r->F64();
  return v;
}

void PutInts(ByteWriter* w, const std::vector<int>& v) {
  w->Size(v.size());
  for (int x : v) w->I32(x);
}
void GetInts(ByteReader* r, std::vector<int>* v) {
  v->resize(r->Count(sizeof(int32_t)));
  for (int& x : *v) x = r->I32();
}

void PutVectors(ByteWriter* w, const std::vector<Eigen::Vector3d>& v) {
  w->Size(v.size());
  for (const Eigen::Vector3d& x : v) PutVector3(w, x);
}
void GetVectors(ByteReader* r, std::vector<Eigen::Vector3d>* v) {
  v->resize(r->Count(3 * sizeof(double)));
  for (Eigen::Vector3d& x : *v) x = GetVector3(r);
}

// Every counter, in declaration order: a new field must be added here (the size check). The
// four time sums (partial, correction, batch, incremental seconds) are this process's, as the
// server's update timings: not written (a restored smoother counts from 0), so that two
// servers in the same state write the same bytes.
static_assert(sizeof(SmootherStats) == 28 * 8, "SmootherStats changed: update the codec");
template <typename Stats, typename OnInt>
void ForEachCount(Stats& s, OnInt on_int) {
  for (auto* v : {&s.updates,
                  &s.batch_steps,
                  &s.batch_steps_on_clock,
                  &s.batch_steps_on_fill,
                  &s.batch_steps_on_merge,
                  &s.batch_steps_on_drift,
                  &s.failed_batch_steps,
                  &s.partial_relinearizations,
                  &s.relinearized_variables,
                  &s.rows_reeliminated,
                  &s.rows_before_closure,
                  &s.rows_in_tails,
                  &s.partial_merges,
                  &s.batch_iterations,
                  &s.iterations_to_convergence,
                  &s.givens_block_rows,
                  &s.givens_block_columns,
                  &s.rows_backsubstituted,
                  &s.correction_steps,
                  &s.correction_stalls,
                  &s.correction_skips,
                  &s.variables,
                  &s.factors,
                  &s.nnz_r}) {
    on_int(v);
  }
}

}  // namespace

void PutSmootherState(ByteWriter* w, uint32_t snapshot_version, const SmootherState& s) {
  w->Size(s.variables.size());
  for (const SmootherState::Variable& v : s.variables) {
    w->Pose(v.linearization);
    w->I32(v.position);
  }
  w->Size(s.factors.size());
  for (const SmootherState::FactorState& f : s.factors) {
    w->Bool(f.active);
    w->Bool(f.in_r);
    for (const Pose2& at : f.at) w->Pose(at);
  }
  w->Size(s.pending_factors.size());
  for (int64_t f : s.pending_factors) w->I64(f);
  PutInts(w, s.pending_variables);
  w->Size(s.grounded.size());
  for (uint8_t g : s.grounded) w->U8(g);
  PutInts(w, s.position_to_variable);
  PutVectors(w, s.delta);
  PutVectors(w, s.correction);
  w->Bool(s.correction_converged);
  w->F64(s.last_chi2);
  // A format with no room for the factors since the last correction (before 8) or for the
  // local corrections' moves (before 11) writes an infinite bound when it leaves any out:
  // the restored smoother then corrects the whole map at its next update instead of
  // skipping on a bound that misses them (which clears them).
  const bool local_moves =
      !s.local_pass_values.empty() || !s.local_moved_factors.empty() || s.local_seeds_from > 0;
  const bool left_out = (snapshot_version < 8 && !s.uncorrected_factors.empty()) ||
                        (snapshot_version < 11 && local_moves);
  w->F64(left_out ? std::numeric_limits<double>::infinity() : s.innovation);
  if (snapshot_version >= 8) {
    w->Size(s.uncorrected_factors.size());
    for (int64_t f : s.uncorrected_factors) w->I64(f);
  }
  if (snapshot_version >= 11) {
    w->Size(s.local_pass_values.size());
    for (const SmootherState::PassValue& p : s.local_pass_values) {
      w->I32(p.variable);
      w->Pose(p.value);
    }
    w->Size(s.local_moved_factors.size());
    for (int64_t f : s.local_moved_factors) w->I64(f);
    w->I64(s.local_seeds_from);
  }
  w->Size(s.r.rows.size());
  for (const RBlockRow& row : s.r.rows) {
    w->Matrix(row.diagonal);
    w->Size(row.right.size());
    for (const auto& [column, block] : row.right) {
      w->I32(column);
      w->Matrix(block);
    }
    PutVector3(w, row.rhs);
  }
  w->Size(s.r.column_rows.size());
  for (const std::vector<int>& rows : s.r.column_rows) PutInts(w, rows);
  w->I64(s.r.nonzeros);
  w->I64(s.r.eliminated_block_rows);
  w->I64(s.r.eliminated_block_columns);
  w->Bool(s.merge_pending);
  PutInts(w, s.merge_variables);
  w->F64(s.tolerance);
  w->I32(s.updates_since_batch);
  w->I32(s.updates_since_drift_check);
  w->I64(s.nonzeros_after_batch);
  SmootherStats stats = s.stats;
  ForEachCount(stats, [w](int64_t* v) { w->I64(*v); });
  if (snapshot_version >= 12) {
    w->I64(s.aliases);
    w->I64(s.measurements_inside_nodes);
  }
}

void GetSmootherState(ByteReader* r, uint32_t snapshot_version, SmootherState* s) {
  s->variables.resize(r->Count(3 * sizeof(double) + sizeof(int32_t)));
  for (SmootherState::Variable& v : s->variables) {
    v.linearization = r->Pose();
    v.position = r->I32();
  }
  s->factors.resize(r->Count(2));
  for (SmootherState::FactorState& f : s->factors) {
    f.active = r->Bool();
    f.in_r = r->Bool();
    for (Pose2& at : f.at) at = r->Pose();
  }
  s->pending_factors.resize(r->Count(sizeof(int64_t)));
  for (int64_t& f : s->pending_factors) f = r->I64();
  GetInts(r, &s->pending_variables);
  s->grounded.resize(r->Count());
  for (uint8_t& g : s->grounded) g = r->U8();
  GetInts(r, &s->position_to_variable);
  GetVectors(r, &s->delta);
  GetVectors(r, &s->correction);
  s->correction_converged = r->Bool();
  s->last_chi2 = r->F64();
  s->innovation = r->F64();
  s->uncorrected_factors.clear();  // before version 8 none was kept
  if (snapshot_version >= 8) {
    s->uncorrected_factors.resize(r->Count(sizeof(int64_t)));
    for (int64_t& f : s->uncorrected_factors) f = r->I64();
  }
  s->local_pass_values.clear();  // before version 11 none was kept
  s->local_moved_factors.clear();
  s->local_seeds_from = 0;
  if (snapshot_version >= 11) {
    s->local_pass_values.resize(r->Count(sizeof(int32_t) + 3 * sizeof(double)));
    for (SmootherState::PassValue& p : s->local_pass_values) {
      p.variable = r->I32();
      p.value = r->Pose();
    }
    s->local_moved_factors.resize(r->Count(sizeof(int64_t)));
    for (int64_t& f : s->local_moved_factors) f = r->I64();
    s->local_seeds_from = r->I64();
  }
  s->r.rows.resize(r->Count(12 * sizeof(double)));
  for (RBlockRow& row : s->r.rows) {
    row.diagonal = r->Matrix();
    row.right.resize(r->Count(sizeof(int32_t) + 9 * sizeof(double)));
    for (auto& [column, block] : row.right) {
      column = r->I32();
      block = r->Matrix();
    }
    row.rhs = GetVector3(r);
  }
  s->r.column_rows.resize(r->Count(sizeof(uint64_t)));
  for (std::vector<int>& rows : s->r.column_rows) GetInts(r, &rows);
  s->r.nonzeros = r->I64();
  s->r.eliminated_block_rows = r->I64();
  s->r.eliminated_block_columns = r->I64();
  s->merge_pending = r->Bool();
  GetInts(r, &s->merge_variables);
  s->tolerance = r->F64();
  s->updates_since_batch = r->I32();
  s->updates_since_drift_check = r->I32();
  s->nonzeros_after_batch = r->I64();
  s->stats = SmootherStats{};
  ForEachCount(s->stats, [r](int64_t* v) { *v = r->I64(); });
  s->aliases = 0;  // before version 12 no server folded keyframes
  s->measurements_inside_nodes = 0;
  if (snapshot_version >= 12) {
    s->aliases = r->I64();
    s->measurements_inside_nodes = r->I64();
  }
}

}  // namespace anchormap
