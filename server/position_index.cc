#include "server/position_index.h"

#include <algorithm>
#include <cmath>

namespace anchormap {

void PositionIndex::Clear() {
  cells_.clear();
  size_ = 0;
}

int64_t PositionIndex::Cell(double coordinate) const {
  return static_cast<int64_t>(std::floor(coordinate / cell_m_));
}

uint64_t PositionIndex::CellKey(int64_t cx, int64_t cy) {
  return (static_cast<uint64_t>(cx) << 32) ^ (static_cast<uint64_t>(cy) & 0xffffffffULL);
}

void PositionIndex::Add(int32_t item, const Eigen::Vector2d& position) {
  if (!std::isfinite(position.x()) || !std::isfinite(position.y())) return;
  cells_[CellKey(Cell(position.x()), Cell(position.y()))].push_back({item, position});
  ++size_;
}

std::vector<int32_t> PositionIndex::Near(const Eigen::Vector2d& center, double radius) const {
  std::vector<int32_t> items;
  if (!(radius >= 0) || !std::isfinite(center.x()) || !std::isfinite(center.y())) return items;
  const int64_t x0 = Cell(center.x() - radius), x1 = Cell(center.x() + radius);
  const int64_t y0 = Cell(center.y() - radius), y1 = Cell(center.y() + radius);
  // A radius wider than the stored points: read every cell rather than an empty square.
  if (static_cast<double>(x1 - x0 + 1) * static_cast<double>(y1 - y0 + 1) >
      static_cast<double>(cells_.size())) {
    for (const auto& [key, entries] : cells_) {
      for (const Entry& e : entries) {
        if ((e.position - center).norm() <= radius) items.push_back(e.item);
      }
    }
  } else {
    for (int64_t cx = x0; cx <= x1; ++cx) {
      for (int64_t cy = y0; cy <= y1; ++cy) {
        const auto found = cells_.find(CellKey(cx, cy));
        if (found == cells_.end()) continue;
        for (const Entry& e : found->second) {
          if ((e.position - center).norm() <= radius) items.push_back(e.item);
        }
      }
    }
  }
  std::sort(items.begin(), items.end());
  return items;
}

std::vector<std::pair<int32_t, Eigen::Vector2d>> PositionIndex::Entries() const {
  // Sorted by cell key so that the bytes of a snapshot do not depend on the hash map.
  std::vector<uint64_t> keys;
  keys.reserve(cells_.size());
  for (const auto& [key, entries] : cells_) keys.push_back(key);
  std::sort(keys.begin(), keys.end());
  std::vector<std::pair<int32_t, Eigen::Vector2d>> out;
  out.reserve(size_);
  for (uint64_t key : keys) {
    for (const Entry& e : cells_.at(key)) out.emplace_back(e.item, e.position);
  }
  return out;
}

}  // namespace anchormap
