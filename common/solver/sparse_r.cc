#include "common/solver/sparse_r.h"

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <iterator>
#include <limits>

#include <Eigen/Dense>

#include "common/solver/block_givens.h"

#if defined(__x86_64__) && defined(__GNUC__)
#define ANCHORMAP_SPARSE_R_AVX512 1
#include <immintrin.h>
#endif

namespace anchormap {
namespace {

constexpr int64_t kDiagonalNonZeros = 6;
constexpr int64_t kBlockNonZeros = 9;

// R's block row into rows 0-2 of the work panel, right of the diagonal block: the union's
// block k at columns 3 + 3k (R's block union_in_row[k], or zeros). Each block's 3 x 3
// entries go from column-major to the panel's rows.
void RowToPanel(const RBlockRow& row, const int* union_in_row, int m, double* const upper[3]) {
  for (int k = 0; k < m; ++k) {
    const int to = 3 + 3 * k;
    if (union_in_row[k] >= 0) {
      const double* b = row.right[union_in_row[k]].second.data();
      for (int i = 0; i < 3; ++i) {
        upper[i][to] = b[i];
        upper[i][to + 1] = b[i + 3];
        upper[i][to + 2] = b[i + 6];
      }
    } else {
      for (int i = 0; i < 3; ++i) upper[i][to] = upper[i][to + 1] = upper[i][to + 2] = 0.0;
    }
  }
}

// The panel's rows 0-2 back into R's row `out` (its `right` sized m): block k from columns
// 3 + 3k, column union_columns[k]. The next block row's blocks (next_first, next_bytes:
// addresses, as a prefetch may run past the row's end) are fetched meanwhile, a block's
// worth of lines per block: a row is a few kB, too short for the hardware's stream
// prefetch to warm up on, and all at once they would stall on the outstanding misses.
inline __attribute__((always_inline)) void PrefetchAhead(uintptr_t next_first, uintptr_t next_bytes,
                                                         uintptr_t ahead) {
  if (ahead < next_bytes) {
    __builtin_prefetch(reinterpret_cast<const void*>(next_first + ahead));
    __builtin_prefetch(reinterpret_cast<const void*>(next_first + ahead + 64));
  }
}

inline __attribute__((always_inline)) void PrefetchRest(uintptr_t next_first, uintptr_t next_bytes,
                                                        uintptr_t ahead) {
  for (; ahead < next_bytes; ahead += 64) {
    __builtin_prefetch(reinterpret_cast<const void*>(next_first + ahead));
  }
}

constexpr uintptr_t kBlockBytes = sizeof(std::pair<int, Eigen::Matrix3d>);

void PanelToRow(const double* const upper[3], const int* union_columns, int m, uintptr_t next_first,
                uintptr_t next_bytes, RBlockRow* out) {
  uintptr_t ahead = 0;
  for (int k = 0; k < m; ++k, ahead += kBlockBytes) {
    PrefetchAhead(next_first, next_bytes, ahead);
    const int from = 3 + 3 * k;
    out->right[k].first = union_columns[k];
    double* b = out->right[k].second.data();
    for (int i = 0; i < 3; ++i) {
      b[i] = upper[i][from];
      b[i + 3] = upper[i][from + 1];
      b[i + 6] = upper[i][from + 2];
    }
  }
  PrefetchRest(next_first, next_bytes, ahead);
}

#ifdef ANCHORMAP_SPARSE_R_AVX512
// The same two copies with AVX-512 permutations: a block's nine entries in three stores (or
// two and a scalar) instead of nine. Moves only, so the same bits.
bool UseAvx512Copies() {
  static const bool has = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx512f") != 0;
  }();
  return has && SparseR::VectorCopiesAllowed().load(std::memory_order_relaxed);
}

__attribute__((target("avx512f"))) void RowToPanelAvx512(const RBlockRow& row,
                                                         const int* union_in_row, int m,
                                                         double* const upper[3]) {
  // Row i of a column-major block is entries i, i + 3, i + 6 (8: the second source). The
  // intrinsics are the zero-masked forms: GCC 12 warns on the others' undefined inputs.
  const __m512i row0 = _mm512_setr_epi64(0, 3, 6, 0, 0, 0, 0, 0);
  const __m512i row1 = _mm512_setr_epi64(1, 4, 7, 0, 0, 0, 0, 0);
  const __m512i row2 = _mm512_setr_epi64(2, 5, 8, 0, 0, 0, 0, 0);
  constexpr __mmask8 kAll = 0xFF, kThree = 0x07;
  const __m512d zero = _mm512_setzero_pd();
  for (int k = 0; k < m; ++k) {
    const int to = 3 + 3 * k;
    if (union_in_row[k] >= 0) {
      const double* b = row.right[union_in_row[k]].second.data();
      const __m512d first8 = _mm512_loadu_pd(b);
      const __m512d last = _mm512_set1_pd(b[8]);
      _mm512_mask_storeu_pd(upper[0] + to, kThree, _mm512_maskz_permutexvar_pd(kAll, row0, first8));
      _mm512_mask_storeu_pd(upper[1] + to, kThree, _mm512_maskz_permutexvar_pd(kAll, row1, first8));
      _mm512_mask_storeu_pd(upper[2] + to, kThree,
                            _mm512_maskz_permutex2var_pd(kAll, first8, row2, last));
    } else {
      for (int i = 0; i < 3; ++i) _mm512_mask_storeu_pd(upper[i] + to, kThree, zero);
    }
  }
}

__attribute__((target("avx512f"))) void PanelToRowAvx512(const double* const upper[3],
                                                         const int* union_columns, int m,
                                                         uintptr_t next_first, uintptr_t next_bytes,
                                                         RBlockRow* out) {
  // Column-major entries 0-7 of a block from rows 0 and 1 (lanes 0-2 and 4-6 of the first
  // source) and row 2 (lanes 0-1 of the second); entry 8 is row 2's third.
  const __m512i column_major = _mm512_setr_epi64(0, 4, 8, 1, 5, 9, 2, 6);
  constexpr __mmask8 kAll = 0xFF, kThree = 0x07;
  uintptr_t ahead = 0;
  for (int k = 0; k < m; ++k, ahead += kBlockBytes) {
    PrefetchAhead(next_first, next_bytes, ahead);
    const int from = 3 + 3 * k;
    const __m512d rows01 = _mm512_maskz_insertf64x4(
        kAll, _mm512_maskz_loadu_pd(kThree, upper[0] + from), _mm256_loadu_pd(upper[1] + from), 1);
    const __m512d row2 = _mm512_maskz_loadu_pd(kThree, upper[2] + from);
    out->right[k].first = union_columns[k];
    double* b = out->right[k].second.data();
    _mm512_storeu_pd(b, _mm512_maskz_permutex2var_pd(kAll, rows01, column_major, row2));
    b[8] = upper[2][from + 2];
  }
  PrefetchRest(next_first, next_bytes, ahead);
}
#endif

// The copies the CPU runs best: the AVX-512 ones where it has them (the same bits).
void CopyRowToPanel(const RBlockRow& row, const int* union_in_row, int m, double* const upper[3]) {
#ifdef ANCHORMAP_SPARSE_R_AVX512
  if (UseAvx512Copies()) return RowToPanelAvx512(row, union_in_row, m, upper);
#endif
  RowToPanel(row, union_in_row, m, upper);
}

void CopyPanelToRow(const double* const upper[3], const int* union_columns, int m,
                    uintptr_t next_first, uintptr_t next_bytes, RBlockRow* out) {
#ifdef ANCHORMAP_SPARSE_R_AVX512
  if (UseAvx512Copies()) {
    return PanelToRowAvx512(upper, union_columns, m, next_first, next_bytes, out);
  }
#endif
  PanelToRow(upper, union_columns, m, next_first, next_bytes, out);
}

}  // namespace

std::atomic<bool>& SparseR::VectorCopiesAllowed() {
  static std::atomic<bool> allowed{true};
  return allowed;
}

uint64_t SparseR::InstanceId::Next() {
  static std::atomic<uint64_t> next{1};
  return next.fetch_add(1, std::memory_order_relaxed);
}

int SparseR::FirstRowChangedAfter(uint64_t revision) const {
  for (int p = 0; p < size(); ++p) {
    if (row_revision_[p] > revision) return p;
  }
  return size();
}

void SparseR::Append(int count) {
  BeginChange();
  rows_.resize(rows_.size() + count);
  column_rows_.resize(rows_.size());
  row_revision_.resize(rows_.size(), revision_);
}

void SparseR::Truncate(int n) {
  BeginChange();
  rows_.resize(n);
  column_rows_.resize(n);
  row_revision_.resize(n);
}

void SparseR::Assign(std::vector<RBlockRow> rows) {
  BeginChange();
  rows_ = std::move(rows);
  StampAll();
  column_rows_.assign(rows_.size(), {});
  nonzeros_ = 0;
  for (int p = 0; p < size(); ++p) {
    nonzeros_ += kDiagonalNonZeros + kBlockNonZeros * static_cast<int64_t>(rows_[p].right.size());
    for (const auto& [q, block] : rows_[p].right) column_rows_[q].push_back(p);
  }
}

double SparseR::Eliminate(NewRows rows, std::vector<int>* touched) {
  std::vector<NewRows> one;
  one.push_back(std::move(rows));
  return Eliminate(std::move(one), touched);
}

double SparseR::Eliminate(std::vector<NewRows> rows, std::vector<int>* touched) {
  double leftover = 0.0;
  constexpr int64_t kNoBudget = std::numeric_limits<int64_t>::max();
  EliminateWithin(std::move(rows), kNoBudget, kNoBudget, touched, &leftover);
  return leftover;
}

bool SparseR::WorkCouldPass(const std::vector<NewRows>& rows, int64_t max_fill,
                            int64_t max_work) const {
  // Every row met takes at most all the triples; the rows met span at most R's blocks and
  // the fill (within its budget), one block per diagonal, or (rows after c) the blocks
  // right of c.
  int first = size();
  for (const NewRows& r : rows) {
    for (const auto& entry : r.blocks) first = std::min(first, entry.first);
  }
  const int64_t k = size() - first;
  int64_t spanned = k * (k + 1) / 2;
  if (max_fill < std::numeric_limits<int64_t>::max()) {
    spanned = std::min(spanned, (nonzeros_ + max_fill) / kBlockNonZeros + k);
  }
  const int64_t triples = static_cast<int64_t>(rows.size());
  return spanned > 0 && triples > max_work / spanned;
}

int64_t SparseR::PredictedWork(const std::vector<NewRows>& rows, int64_t max_work) const {
  // Eliminate's walk on patterns: the lowest leading column c of the carries; the carries
  // leading with c merge, and R's row c and the merged carry both take the union of their
  // columns right of c; the work there is the triples met times the union's blocks and the
  // diagonal. Each row is met once (c only grows), so R's own patterns are read. Exact
  // zeros aside (they drop blocks and triples), it is Eliminate's work.
  struct Pattern {
    std::vector<int> columns;  // sorted
    int64_t triples = 0;
  };
  std::vector<Pattern> carries;
  carries.reserve(rows.size());
  for (const NewRows& r : rows) {
    Pattern carry;
    for (const auto& entry : r.blocks) carry.columns.push_back(entry.first);
    std::sort(carry.columns.begin(), carry.columns.end());
    carry.columns.erase(std::unique(carry.columns.begin(), carry.columns.end()),
                        carry.columns.end());
    carry.triples = 1;
    if (!carry.columns.empty()) carries.push_back(std::move(carry));
  }
  int64_t work = 0;
  std::vector<int> merged, merged_next;
  while (!carries.empty() && work <= max_work) {
    int c = carries.front().columns.front();
    for (const Pattern& carry : carries) c = std::min(c, carry.columns.front());
    const RBlockRow& row = rows_[c];
    merged.clear();
    for (const auto& entry : row.right) merged.push_back(entry.first);
    // The meeting carries leave; the first one's slot is kept for the merged carry.
    int64_t triples = 0;
    size_t kept = 0, slot = carries.size();
    for (size_t i = 0; i < carries.size(); ++i) {
      if (carries[i].columns.front() == c) {
        triples += carries[i].triples;
        merged_next.clear();
        std::set_union(merged.begin(), merged.end(), carries[i].columns.begin() + 1,
                       carries[i].columns.end(), std::back_inserter(merged_next));
        merged.swap(merged_next);
        if (slot < carries.size()) continue;
        slot = kept;
      }
      if (kept != i) std::swap(carries[kept], carries[i]);
      ++kept;
    }
    carries.resize(kept);
    work += triples * static_cast<int64_t>(merged.size() + 1);
    // An empty row takes the first triple whole (its rotations are exact swaps), the
    // others go on; nothing goes on past the last column.
    const bool was_empty = row.diagonal.isZero(0.0) && row.right.empty();
    const int64_t going_on = merged.empty() ? 0 : triples - (was_empty ? 1 : 0);
    if (going_on > 0) {
      carries[slot].columns.swap(merged);
      carries[slot].triples = going_on;
    } else {
      std::swap(carries[slot], carries.back());
      carries.pop_back();
    }
  }
  return work;
}

bool SparseR::EliminateWithin(std::vector<NewRows> rows, int64_t max_fill, int64_t max_work,
                              std::vector<int>* touched, double* leftover_out) {
  // The work budget is tested first, on the walk's patterns alone (PredictedWork), when
  // a bound says it could be passed: stopping the arithmetic there would have spent the
  // budget. While the fill budget could still be passed, the new block rows are written
  // aside (staged_), so that an update past it leaves R as it was: the fill is known at
  // each row met before any arithmetic there (the union of the columns), so the walk stops
  // at once. As soon as the rows left cannot pass it (row c' can gain at most the blocks
  // right of it and a diagonal), the staged rows are committed and the rest is written in
  // place, as without a budget: the dense rows near the root, where most of the work is,
  // are never staged.
  const int64_t n = size();
  auto most_fill_from = [n](int64_t c) {  // of the block rows c..n-1
    const int64_t k = n - c;
    return kBlockNonZeros * k * (k - 1) / 2 + kDiagonalNonZeros * k;
  };
  if (max_work < std::numeric_limits<int64_t>::max() && WorkCouldPass(rows, max_fill, max_work) &&
      PredictedWork(rows, max_work) > max_work) {
    return false;
  }
  bool staging = true;
  int staged = 0;
  staged_positions_.clear();
  new_references_.clear();
  int64_t fill = 0, met_rows = 0, met_columns = 0, work = 0;  // met, work: work counters
  // Commits the staged rows (in the order they were met; their old storage is kept for the
  // next call) and starts writing in place.
  auto commit = [&]() {
    BeginChange();
    for (int i = 0; i < staged; ++i) {
      const int c = staged_positions_[i];
      RBlockRow& row = rows_[c];
      row.diagonal = staged_[i].diagonal;
      row.right.swap(staged_[i].right);
      row.rhs = staged_[i].rhs;
      Stamp(c);
      if (touched) touched->push_back(c);
    }
    for (const auto& [q, c] : new_references_) column_rows_[q].push_back(c);
    staging = false;
  };
  // Each measurement starts as its own carry: a row-major panel by sorted column (a key
  // repeated within one measurement has its blocks summed).
  auto by_column = [](const auto& x, const auto& y) { return x.first < y.first; };
  if (carries_.size() < rows.size()) carries_.resize(rows.size());
  double leftover = 0.0;
  for (size_t i = 0; i < rows.size(); ++i) {
    Carry& carry = carries_[i];
    std::sort(rows[i].blocks.begin(), rows[i].blocks.end(), by_column);
    carry.columns.clear();
    for (const auto& [q, block] : rows[i].blocks) {
      if (carry.columns.empty() || carry.columns.back() != q) carry.columns.push_back(q);
    }
    const int width = 3 * static_cast<int>(carry.columns.size()) + 1;
    if (carry.panel.rows() < 3 || carry.panel.cols() < width) carry.panel.resize(3, 2 * width);
    carry.panel.topLeftCorner(3, width).setZero();
    for (size_t b = 0, k = 0; b < rows[i].blocks.size(); ++b) {
      while (carry.columns[k] != rows[i].blocks[b].first) ++k;
      carry.panel.block(0, 3 * k, 3, 3) += rows[i].blocks[b].second;
    }
    carry.panel.block<3, 1>(0, width - 1) = rows[i].rhs;
    carry.at.resize(carry.columns.size());
    for (size_t j = 0; j < carry.columns.size(); ++j) carry.at[j] = 3 * static_cast<int>(j);
    carry.rhs_at = width - 1;
    carry.first_row = 0;
    carry.triples = 1;
    carry.alive = !carry.columns.empty();
    if (!carry.alive) leftover += rows[i].rhs.squaredNorm();  // no variable to absorb it
  }

  while (true) {
    // The lowest column any carry still has a block in; every carry that leads with it
    // meets R's row there together.
    int c = -1;
    for (size_t i = 0; i < rows.size(); ++i) {
      const Carry& carry = carries_[i];
      if (carry.alive && (c < 0 || carry.columns.front() < c)) c = carry.columns.front();
    }
    if (c < 0) break;
    meeting_.clear();
    int triples = 0;
    for (size_t i = 0; i < rows.size(); ++i) {
      if (carries_[i].alive && carries_[i].columns.front() == c) {
        meeting_.push_back(static_cast<int>(i));
        triples += carries_[i].triples;
      }
    }
    if (staging && fill + most_fill_from(c) <= max_fill) commit();
    RBlockRow& row = rows_[c];
    const bool was_empty = row.diagonal.isZero(0.0) && row.right.empty();

    // Union of the columns right of c in R's row and in the meeting carries (all sorted).
    union_columns_.clear();
    for (const auto& entry : row.right) union_columns_.push_back(entry.first);
    for (int i : meeting_) {
      const std::vector<int>& columns = carries_[i].columns;
      merged_columns_.clear();
      std::set_union(union_columns_.begin(), union_columns_.end(), columns.begin() + 1,
                     columns.end(), std::back_inserter(merged_columns_));
      union_columns_.swap(merged_columns_);
    }
    const int m = static_cast<int>(union_columns_.size());
    // The next block row met is most likely the union's first column: its row's storage is
    // cold (R is larger than the cache), so its header is fetched now and its blocks after
    // the rotations.
    if (m > 0) __builtin_prefetch(&rows_[union_columns_[0]]);
    union_in_row_.assign(m, -1);
    for (int k = 0, r = 0; r < static_cast<int>(row.right.size()); ++k) {
      if (union_columns_[k] == row.right[r].first) union_in_row_[k] = r++;
    }
    const size_t old_right = row.right.size();
    fill +=
        kBlockNonZeros * static_cast<int64_t>(m - old_right) + (was_empty ? kDiagonalNonZeros : 0);
    if (fill > max_fill) return false;  // still staging: nothing written
    ++met_rows;
    met_columns += m + 1;
    work += static_cast<int64_t>(triples) * (m + 1);
    const int width = 3 + 3 * m + 1;
    const int panel_rows = 3 + 3 * triples;
    if (work_.rows() < panel_rows || work_.cols() < width) {
      work_.resize(std::max<Eigen::Index>(work_.rows(), panel_rows), 2 * width);
    }
    const int stride = static_cast<int>(work_.cols());

    // Rows 0-2: R's row, block by block (each block's 9 entries read once, column-major).
    {
      double* upper[3] = {work_.row(0).data(), work_.row(1).data(), work_.row(2).data()};
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) upper[i][j] = row.diagonal(i, j);
      }
      CopyRowToPanel(row, union_in_row_.data(), m, upper);
      for (int i = 0; i < 3; ++i) upper[i][width - 1] = row.rhs(i);
    }
    // Then each meeting carry's rows, spread over the union's columns.
    int next_row = 3;
    for (int i : meeting_) {
      Carry& carry = carries_[i];
      const int n = static_cast<int>(carry.columns.size());
      carry.in_union.resize(n);
      for (int j = 1, k = 0; j < n; ++j) {
        while (union_columns_[k] != carry.columns[j]) ++k;
        carry.in_union[j] = 3 + 3 * k;
      }
      // Columns adjacent both in the carry and in the union are copied as one run (a
      // carry mostly holds a stretch of the last row's union), the gaps between runs zeroed.
      runs_.clear();
      for (int j = 1; j < n; ++j) {
        if (!runs_.empty() && runs_.back().to + runs_.back().count == carry.in_union[j] &&
            runs_.back().from + runs_.back().count == carry.at[j]) {
          runs_.back().count += 3;
        } else {
          runs_.push_back({carry.in_union[j], carry.at[j], 3});
        }
      }
      const int lead = carry.at[0];
      for (int r = 0; r < 3 * carry.triples; ++r, ++next_row) {
        double* lower = work_.row(next_row).data();
        const double* from = carry.panel.row(carry.first_row + r).data();
        lower[0] = from[lead];
        lower[1] = from[lead + 1];
        lower[2] = from[lead + 2];
        int zero_from = 3;
        for (const Run& run : runs_) {
          std::fill(lower + zero_from, lower + run.to, 0.0);
          std::copy(from + run.from, from + run.from + run.count, lower + run.to);
          zero_from = run.to + run.count;
        }
        std::fill(lower + zero_from, lower + width - 1, 0.0);
        lower[width - 1] = from[carry.rhs_at];
      }
    }

    // Zero the carried rows under the diagonal block, one triple after another.
    for (int t = 0; t < triples; ++t) {
      EliminateBlockRow(work_.data(), work_.row(3 + 3 * t).data(), stride, width);
    }
    // That row's blocks are fetched while this one is written out, a block's worth of lines
    // per block: a row is a few kB, too short for the hardware's stream prefetch to warm up
    // on, and all at once they would stall on the outstanding misses.
    // As addresses, not pointers: a prefetch may run past the row's end (or the row may be
    // empty), where pointer arithmetic would be undefined.
    uintptr_t next_first = 0;
    uintptr_t next_bytes = 0;
    if (m > 0) {
      const auto& next = rows_[union_columns_[0]].right;
      next_first = reinterpret_cast<uintptr_t>(next.data());
      next_bytes = next.size() * sizeof(next[0]);
    }

    // R's new row, staged or in place (new fill registers in the column index).
    if (static_cast<size_t>(m) != old_right) {
      for (int k = 0; k < m; ++k) {
        if (union_in_row_[k] >= 0) continue;
        if (staging) {
          new_references_.emplace_back(union_columns_[k], c);
        } else {
          column_rows_[union_columns_[k]].push_back(c);
        }
      }
    }
    RBlockRow* out = &row;
    if (staging) {
      if (static_cast<int>(staged_.size()) == staged) staged_.emplace_back();
      out = &staged_[staged++];
      staged_positions_.push_back(c);
    } else {
      Stamp(c);
      if (touched) touched->push_back(c);
    }
    {
      const double* upper[3] = {work_.row(0).data(), work_.row(1).data(), work_.row(2).data()};
      double* d = out->diagonal.data();
      for (int i = 0; i < 3; ++i) {
        d[i] = upper[i][0];
        d[i + 3] = upper[i][1];
        d[i + 6] = upper[i][2];
        out->rhs(i) = upper[i][width - 1];
      }
      out->right.resize(m);
      CopyPanelToRow(upper, union_columns_.data(), m, next_first, next_bytes, out);
    }

    // The meeting carries continue as one: the triples that still have a block anywhere,
    // over the columns where some row is not zero. A triple with no block left has only
    // its residual, which no variable can absorb.
    Carry& merged = carries_[meeting_.front()];
    for (size_t k = 1; k < meeting_.size(); ++k) carries_[meeting_[k]].alive = false;
    auto all_zero = [](const double* first, const double* last) {
      for (; first != last; ++first) {
        if (*first != 0.0) return false;
      }
      return true;
    };
    int kept = 0;
    for (int t = 0; t < triples; ++t) {
      bool empty = true;
      for (int r = 0; r < 3 && empty; ++r) {
        const double* lower = work_.row(3 + 3 * t + r).data();
        empty = all_zero(lower + 3, lower + width - 1);
      }
      if (empty) {
        leftover += work_.block(3 + 3 * t, width - 1, 3, 1).squaredNorm();
        continue;
      }
      if (kept != t) {
        work_.block(3 + 3 * kept, 0, 3, width) = work_.block(3 + 3 * t, 0, 3, width);
      }
      ++kept;
    }
    merged.columns.clear();
    merged.at.clear();
    merged.triples = kept;
    merged.alive = kept > 0;
    if (!merged.alive) continue;
    // The kept rows stay where they are: the work panel becomes the carry's, and the
    // carry's old panel the next work panel.
    const int kept_rows = 3 * kept;
    for (int k = 0; k < m; ++k) {
      const int from = 3 + 3 * k;
      bool zero = true;
      for (int r = 0; r < kept_rows && zero; ++r) {
        const double* lower = work_.row(3 + r).data() + from;
        zero = lower[0] == 0.0 && lower[1] == 0.0 && lower[2] == 0.0;
      }
      if (zero) continue;
      merged.columns.push_back(union_columns_[k]);
      merged.at.push_back(from);
    }
    merged.first_row = 3;
    merged.rhs_at = width - 1;
    merged.panel.swap(work_);
  }

  if (staging) commit();  // within the budget
  nonzeros_ += fill;
  eliminated_block_rows_ += met_rows;
  eliminated_block_columns_ += met_columns;
  eliminated_work_ += work;
  *leftover_out = leftover;
  return true;
}

void SparseR::ReplaceTail(int p0, const std::vector<int>& new_position,
                          const std::vector<int>& kept, std::vector<RBlockRow> rows,
                          const std::vector<std::pair<int, Eigen::Vector3d>>& rhs) {
  BeginChange();
  const int n = size();
  for (const auto& [p, value] : rhs) {
    rows_[p].rhs = value;
    Stamp(p);
  }
  auto by_column = [](const auto& x, const auto& y) { return x.first < y.first; };
  auto renumber = [&](RBlockRow* row) {
    // Entries before p0 keep their (sorted) place; the tail's are renumbered and sorted.
    auto first =
        std::lower_bound(row->right.begin(), row->right.end(), p0,
                         [](const auto& entry, int column) { return entry.first < column; });
    for (auto it = first; it != row->right.end(); ++it) it->first = new_position[it->first - p0];
    std::sort(first, row->right.end(), by_column);
  };
  // Rows before p0 that reference the tail.
  std::vector<char>& mark = scratch_dirty_;
  mark.assign(p0, 0);
  std::vector<int> head_rows;
  for (int q = p0; q < n; ++q) {
    for (int r : column_rows_[q]) {
      if (r < p0 && !mark[r]) {
        mark[r] = 1;
        head_rows.push_back(r);
      }
    }
  }
  std::sort(head_rows.begin(), head_rows.end());
  for (int r : head_rows) {
    renumber(&rows_[r]);
    Stamp(r);
  }

  std::vector<RBlockRow> tail;
  tail.reserve(n - p0);
  for (int p = p0; p < n; ++p) {
    nonzeros_ -= kDiagonalNonZeros + kBlockNonZeros * static_cast<int64_t>(rows_[p].right.size());
  }
  for (int p : kept) {
    tail.push_back(std::move(rows_[p]));
    renumber(&tail.back());
  }
  for (RBlockRow& row : rows) tail.push_back(std::move(row));
  rows_.resize(p0);
  for (RBlockRow& row : tail) {
    nonzeros_ += kDiagonalNonZeros + kBlockNonZeros * static_cast<int64_t>(row.right.size());
    rows_.push_back(std::move(row));
  }
  for (int p = p0; p < n; ++p) Stamp(p);
  for (int q = p0; q < n; ++q) column_rows_[q].clear();
  for (int r : head_rows) {
    for (const auto& [q, block] : rows_[r].right) {
      if (q >= p0) column_rows_[q].push_back(r);
    }
  }
  for (int p = p0; p < n; ++p) {
    for (const auto& [q, block] : rows_[p].right) column_rows_[q].push_back(p);
  }
}

bool SparseR::ImportState(State state) {
  if (state.column_rows.size() != state.rows.size()) return false;
  const int n = static_cast<int>(state.rows.size());
  for (const std::vector<int>& referencing : state.column_rows) {
    for (int r : referencing) {
      if (r < 0 || r >= n) return false;
    }
  }
  for (const RBlockRow& row : state.rows) {
    for (const auto& [q, block] : row.right) {
      if (q < 0 || q >= n) return false;
    }
  }
  BeginChange();
  rows_ = std::move(state.rows);
  StampAll();
  column_rows_ = std::move(state.column_rows);
  nonzeros_ = state.nonzeros;
  eliminated_block_rows_ = state.eliminated_block_rows;
  eliminated_block_columns_ = state.eliminated_block_columns;
  return true;
}

Eigen::Vector3d SparseR::SolveRow(int p, const std::vector<Eigen::Vector3d>& delta) const {
  const RBlockRow& row = rows_[p];
  Eigen::Vector3d v = row.rhs;
  for (const auto& [q, block] : row.right) v.noalias() -= block * delta[q];
  return row.diagonal.triangularView<Eigen::Upper>().solve(v);
}

void SparseR::BackSubstitute(std::vector<Eigen::Vector3d>* delta) const {
  delta->resize(rows_.size());
  for (int p = size() - 1; p >= 0; --p) (*delta)[p] = SolveRow(p, *delta);
}

void SparseR::BackSubstituteTail(int from, std::vector<Eigen::Vector3d>* x) const {
  x->resize(rows_.size());
  for (int p = size() - 1; p >= from; --p) (*x)[p] = SolveRow(p, *x);
}

int SparseR::BackSubstitutePartial(const std::vector<int>& dirty, double threshold,
                                   std::vector<Eigen::Vector3d>* delta) {
  delta->resize(rows_.size(), Eigen::Vector3d::Zero());
  // Rows are solved in decreasing position; a row only ever marks rows above it, so one
  // downward sweep over a bitmap visits each dirty row once (cheaper than a heap).
  std::vector<char>& mark = scratch_dirty_;
  mark.assign(rows_.size(), 0);
  int highest = -1;
  for (int p : dirty) {
    mark[p] = 1;
    highest = std::max(highest, p);
  }
  int recomputed = 0;
  for (int p = highest; p >= 0; --p) {
    if (!mark[p]) continue;
    const Eigen::Vector3d value = SolveRow(p, *delta);
    const double change = (value - (*delta)[p]).cwiseAbs().maxCoeff();
    (*delta)[p] = value;
    ++recomputed;
    if (change > threshold) {
      for (int r : column_rows_[p]) mark[r] = 1;
    }
  }
  return recomputed;
}

double SparseR::MinAbsDiagonal() const {
  double smallest = std::numeric_limits<double>::infinity();
  for (const RBlockRow& row : rows_) {
    smallest = std::min(smallest, row.diagonal.diagonal().cwiseAbs().minCoeff());
  }
  return smallest;
}

std::vector<Eigen::Vector3d> SolveTransposed(const std::vector<RBlockRow>& rows,
                                             std::vector<Eigen::Vector3d> g) {
  // R^T y = g: block row p of R^T is column p of R, so process positions upwards and
  // push each solved y_p into the later entries it touches.
  for (size_t p = 0; p < rows.size(); ++p) {
    g[p] = rows[p].diagonal.transpose().triangularView<Eigen::Lower>().solve(g[p]);
    for (const auto& [q, block] : rows[p].right) g[q].noalias() -= block.transpose() * g[p];
  }
  return g;
}

}  // namespace anchormap
