#include "server/submap_cache.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "common/geometry/angle.h"

namespace anchormap {

Status SubmapCacheOptions::Validate() const {
  if (!(budget_mb >= 0)) return Status::Error("submap cache budget_mb must be >= 0");
  if (!(reuse_m >= 0) || !(reuse_rad >= 0))
    return Status::Error("submap cache reuse_m and reuse_rad must be >= 0");
  return Status::Ok();
}

std::string SubmapCacheStats::Summary(const std::string& name) const {
  char text[256];
  std::snprintf(text, sizeof(text),
                "%s_submaps: hits %lld builds %lld evictions %lld held %lld mb %.0f peak_mb %.0f",
                name.c_str(), static_cast<long long>(hits), static_cast<long long>(builds),
                static_cast<long long>(evictions), static_cast<long long>(held),
                static_cast<double>(bytes) / 1e6, static_cast<double>(peak_bytes) / 1e6);
  return text;
}

size_t ReferenceBytes(const ScanReference& reference) {
  // Per cell: the field's vector (2 floats) and nearest primitive (int32), the likelihood (the
  // pyramid's level 0, a float), and a byte per level above it (each a little wider than the
  // grid): the local and global searches bound on the bytes, built on the first search. (The
  // wide loop searches' float levels are built only for their own submaps, which are not kept.)
  const size_t per_cell = 8 + 4 + 4 + static_cast<size_t>(reference.options().num_levels - 1);
  return reference.geometry().num_cells() * per_cell;
}

bool SubmapCache::Reusable(const SubmapDrawing& cached, const SubmapDrawing& drawing) const {
  if (cached.T_center_keyframes.size() != drawing.T_center_keyframes.size()) return false;
  for (size_t i = 0; i < drawing.T_center_keyframes.size(); ++i) {
    const auto& [index_a, pose_a] = cached.T_center_keyframes[i];
    const auto& [index_b, pose_b] = drawing.T_center_keyframes[i];
    if (index_a != index_b) return false;
    // Exact equality first: with no tolerance, only the same bits are reused.
    if (pose_a.x() == pose_b.x() && pose_a.y() == pose_b.y() && pose_a.theta() == pose_b.theta())
      continue;
    if ((pose_a.translation() - pose_b.translation()).norm() > options_.reuse_m ||
        std::abs(AngleDifference(pose_a.theta(), pose_b.theta())) > options_.reuse_rad) {
      return false;
    }
  }
  return true;
}

void SubmapCache::Touch(const EntryKey& key, Entry* entry) {
  if (entry->last_use != 0) by_use_.erase(entry->last_use);
  entry->last_use = ++tick_;
  by_use_.emplace(entry->last_use, key);
}

std::shared_ptr<const ScanReference> SubmapCache::Get(const TrajectoryRecord& record,
                                                      const SubmapDrawing& drawing,
                                                      int half_width) {
  if (drawing.num_points == 0) return nullptr;
  const EntryKey key{drawing.center.trajectory.value(), drawing.center.index, half_width};
  auto found = entries_.find(key);
  if (found != entries_.end() && Reusable(found->second.drawing, drawing)) {
    ++stats_.hits;
    Touch(key, &found->second);
    return found->second.reference;
  }
  std::shared_ptr<const ScanReference> reference =
      BuildKeyframeSubmap(record, drawing, max_range_m_, reference_);
  ++stats_.builds;
  if (!reference) return nullptr;
  Entry& entry = entries_[key];
  stats_.bytes -= static_cast<int64_t>(entry.bytes);
  stats_.held += entry.reference ? 0 : 1;
  entry.drawing = drawing;
  entry.reference = reference;
  entry.bytes = ReferenceBytes(*reference);
  stats_.bytes += static_cast<int64_t>(entry.bytes);
  Touch(key, &entry);
  EvictBeyondBudget(key);
  stats_.peak_bytes = std::max(stats_.peak_bytes, stats_.bytes);
  return reference;
}

std::shared_ptr<const ScanReference> SubmapCache::BuildUnkept(const TrajectoryRecord& record,
                                                              const SubmapDrawing& drawing) {
  if (drawing.num_points == 0) return nullptr;
  ++stats_.builds;
  return BuildKeyframeSubmap(record, drawing, max_range_m_, reference_);
}

void SubmapCache::EvictBeyondBudget(const EntryKey& keep) {
  const double budget = options_.budget_mb * 1e6;
  while (static_cast<double>(stats_.bytes) > budget && !by_use_.empty()) {
    const EntryKey oldest = by_use_.begin()->second;
    if (oldest == keep) break;  // the reference just built is always kept
    by_use_.erase(by_use_.begin());
    const auto entry = entries_.find(oldest);
    stats_.bytes -= static_cast<int64_t>(entry->second.bytes);
    --stats_.held;
    ++stats_.evictions;
    entries_.erase(entry);
  }
}

}  // namespace anchormap
