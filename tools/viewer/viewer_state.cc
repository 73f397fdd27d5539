#include "tools/viewer/viewer_state.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include "tools/viewer/base64.h"

namespace anchormap::viewer {

using nlohmann::json;

std::string TrajectoryKey(const std::string& robot, int64_t id) {
  return robot + "/" + std::to_string(id);
}

std::string EncounterKind(const EncounterLink& link) { return ToString(link.kind); }

ViewerState::ViewerState(ViewerStateOptions options) : options_(options) {}

double ViewerState::RoundPosition(double v) const {
  return std::round(v / options_.position_quantum_m) * options_.position_quantum_m;
}

double ViewerState::RoundAngle(double v) const {
  return std::round(v / options_.angle_quantum_rad) * options_.angle_quantum_rad;
}

void ViewerState::Clear() {
  for (const auto& [key, t] : trajectories_) removed_.push_back(key);
  trajectories_.clear();
  if (!encounters_.empty()) encounters_first_changed_ = 0;
  encounters_.clear();
  tiles_.clear();
  tiles_cleared_ = true;
  removed_tiles_.clear();
  grid_run_update_ = -1;
  if (!covariances_.is_null()) covariances_changed_ = true;
  covariances_ = json();
  if (!status_.is_null()) status_changed_ = true;
  status_ = json();
  map_update_ = -1;
  map_utime_ = 0;
  meta_changed_ = true;
}

void ViewerState::NoteUpdate(Stream stream, int64_t update) {
  if (update < last_update_[stream]) {
    ++restarts_;
    restart_inferred_ = true;
    Clear();
    for (int64_t& last : last_update_) last = -1;
  }
  last_update_[stream] = update;
}

bool ViewerState::ApplyMergedMap(const MergedMap& map, int64_t wall_utime) {
  NoteUpdate(kMap, map.update);
  last_message_wall_utime_ = wall_utime;
  map_update_ = map.update;
  map_utime_ = map.utime;
  meta_changed_ = true;

  std::map<std::string, bool> present;
  // A trajectory is named by its robot and its id together (ids of two robots may agree).
  std::map<std::pair<std::string, int64_t>, std::string> key_of_id;
  for (const MergedTrajectory& in : map.trajectories) {
    const std::string key = TrajectoryKey(in.robot, in.trajectory_id);
    present[key] = true;
    key_of_id.emplace(std::make_pair(in.robot, in.trajectory_id), key);
    std::vector<double> poses;
    poses.reserve(3 * in.poses.size());
    for (const Pose2& p : in.poses) {
      poses.push_back(RoundPosition(p.x()));
      poses.push_back(RoundPosition(p.y()));
      poses.push_back(RoundAngle(p.theta()));
    }
    const std::vector<double> anchor = {RoundPosition(in.T_global_local.x()),
                                        RoundPosition(in.T_global_local.y()),
                                        RoundAngle(in.T_global_local.theta())};
    auto [it, added] = trajectories_.try_emplace(key);
    Trajectory& t = it->second;
    if (added) {
      t.robot = in.robot;
      t.id = in.trajectory_id;
      t.first_changed = 0;
      // Removed and back within one delta: the page still holds nothing stale, since
      // "removed" is applied before "trajectories".
      removed_.erase(std::remove(removed_.begin(), removed_.end(), key), removed_.end());
    }
    // The first pose (index) that differs, or the common length.
    const size_t common = std::min(t.poses.size(), poses.size());
    size_t first = 0;
    while (first < common && t.poses[first] == poses[first]) ++first;
    first /= 3;
    const bool poses_changed = t.poses.size() != poses.size() || 3 * first < common;
    if (poses_changed || t.anchored != in.anchored || t.anchor != anchor) {
      t.first_changed = std::min(t.first_changed, poses_changed ? first : poses.size() / 3);
    }
    t.anchored = in.anchored;
    t.anchor = anchor;
    t.poses = std::move(poses);
  }
  for (auto it = trajectories_.begin(); it != trajectories_.end();) {
    if (present.count(it->first)) {
      ++it;
    } else {
      removed_.push_back(it->first);
      it = trajectories_.erase(it);
    }
  }

  std::vector<json> encounters;
  encounters.reserve(map.encounters.size());
  for (const EncounterLink& link : map.encounters) {
    const auto a = key_of_id.find({link.robot_a, link.trajectory_a});
    const auto b = key_of_id.find({link.robot_b, link.trajectory_b});
    if (a == key_of_id.end() || b == key_of_id.end()) {
      rejections_.Count(ErrorCode::kInvalidValue, "merged map",
                        "an encounter link names a trajectory the map does not hold");
      continue;
    }
    encounters.push_back(
        json::array({a->second, link.index_a, b->second, link.index_b, EncounterKind(link)}));
  }
  size_t first = 0;
  const size_t common = std::min(encounters.size(), encounters_.size());
  while (first < common && encounters[first] == encounters_[first]) ++first;
  if (first < common || encounters.size() != encounters_.size()) {
    encounters_first_changed_ = std::min(encounters_first_changed_, first);
  }
  encounters_ = std::move(encounters);
  return true;
}

bool ViewerState::ApplyGridTile(const GridTile& tile, int64_t wall_utime) {
  if (tile.width <= 0 || tile.height <= 0 || tile.width > options_.max_tile_side_cells ||
      tile.height > options_.max_tile_side_cells) {
    rejections_.Count(ErrorCode::kAbsurdSize, "grid tile",
                      "a tile of " + std::to_string(tile.width) + " x " +
                          std::to_string(tile.height) + " cells (at most " +
                          std::to_string(options_.max_tile_side_cells) + " a side)");
    return false;
  }
  if (tile.cells.size() != static_cast<size_t>(tile.width) * static_cast<size_t>(tile.height) ||
      !(tile.resolution_m > 0) || !std::isfinite(tile.resolution_m)) {
    rejections_.Count(ErrorCode::kInvalidValue, "grid tile", "cells or resolution do not fit");
    return false;
  }
  const auto key = std::make_pair(tile.tile_x, tile.tile_y);
  if (tiles_.count(key) == 0 && static_cast<int64_t>(tiles_.size()) >= options_.max_tiles) {
    rejections_.Count(ErrorCode::kQueueFull, "grid tile",
                      "more than " + std::to_string(options_.max_tiles) + " tiles");
    return false;
  }
  NoteUpdate(kTiles, tile.update);
  last_message_wall_utime_ = wall_utime;
  meta_changed_ = true;
  if (tile.update != grid_run_update_) {  // a new grid run: forget tiles it left behind
    grid_run_update_ = tile.update;
    ++grid_run_;
    for (auto it = tiles_.begin(); it != tiles_.end();) {
      if (options_.max_grid_runs_back > 0 &&
          grid_run_ - it->second.run > options_.max_grid_runs_back && it->first != key) {
        removed_tiles_.push_back(std::to_string(it->first.first) + "," +
                                 std::to_string(it->first.second));
        it = tiles_.erase(it);
      } else {
        ++it;
      }
    }
  }
  Tile& t = tiles_[key];
  t.run = grid_run_;
  if (t.cells == tile.cells && t.width == tile.width && t.resolution_m == tile.resolution_m) {
    t.update = tile.update;  // unchanged content: nothing to send
    return true;
  }
  t.x = tile.tile_x;
  t.y = tile.tile_y;
  t.width = tile.width;
  t.height = tile.height;
  t.resolution_m = tile.resolution_m;
  t.update = tile.update;
  t.cells = tile.cells;
  t.changed = true;
  return true;
}

bool ViewerState::ApplyAnchorCovariances(const AnchorCovariances& anchors, int64_t wall_utime) {
  NoteUpdate(kCovariances, anchors.update);
  last_message_wall_utime_ = wall_utime;
  meta_changed_ = true;
  json list = json::array();
  for (const AnchorCovariance& a : anchors.anchors) {
    json cov = json::array();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) cov.push_back(a.covariance(r, c));
    }
    list.push_back({{"key", TrajectoryKey(a.robot, a.trajectory_id)},
                    {"robot", a.robot},
                    {"id", a.trajectory_id},
                    {"anchor",
                     {RoundPosition(a.T_global_local.x()), RoundPosition(a.T_global_local.y()),
                      RoundAngle(a.T_global_local.theta())}},
                    {"cov", cov}});
  }
  json next = {{"update", anchors.update}, {"utime", anchors.utime}, {"anchors", list}};
  if (next != covariances_) {
    covariances_ = std::move(next);
    covariances_changed_ = true;
  }
  return true;
}

bool ViewerState::ApplyStatus(const ServerStatus& status, int64_t wall_utime) {
  // A new instance id is a restart, also when the server resumed from its journal with the
  // same update numbers (then the new instance re-sends the same map).
  if (status.instance_id != 0 && status.instance_id != instance_id_) {
    if (instance_id_ != 0 && !restart_inferred_) {
      ++restarts_;
      Clear();
      for (int64_t& last : last_update_) last = -1;
    }
    instance_id_ = status.instance_id;
  }
  NoteUpdate(kStatus, status.update);
  restart_inferred_ = false;
  last_message_wall_utime_ = wall_utime;
  meta_changed_ = true;
  json rejections = json::object();
  for (const auto& [reason, count] : status.rejections) rejections[reason] = count;
  status_ = {{"utime", status.utime},           {"update", status.update},
             {"robots", status.num_robots},     {"trajectories", status.num_trajectories},
             {"anchored", status.num_anchored}, {"keyframes", status.keyframes},
             {"encounters", status.encounters}, {"last_update_ms", status.last_update_ms},
             {"rejections", rejections}};
  status_changed_ = true;
  return true;
}

bool ViewerState::HasChanges() const {
  if (meta_changed_ || !removed_.empty() || !removed_tiles_.empty() ||
      encounters_first_changed_ != kUnchanged || tiles_cleared_ || covariances_changed_ ||
      status_changed_) {
    return true;
  }
  for (const auto& [key, t] : trajectories_) {
    if (t.first_changed != kUnchanged) return true;
  }
  for (const auto& [key, t] : tiles_) {
    if (t.changed) return true;
  }
  return false;
}

int64_t ViewerState::num_keyframes() const {
  int64_t n = 0;
  for (const auto& [key, t] : trajectories_) n += static_cast<int64_t>(t.poses.size() / 3);
  return n;
}

json ViewerState::TrajectoryJson(const std::string& key, const Trajectory& t, size_t from) const {
  return {{"key", key},
          {"robot", t.robot},
          {"id", t.id},
          {"anchored", t.anchored},
          {"anchor", t.anchor},
          {"num_poses", t.poses.size() / 3},
          {"from", from},
          {"poses", json(std::vector<double>(t.poses.begin() + static_cast<std::ptrdiff_t>(std::min(
                                                                   3 * from, t.poses.size())),
                                             t.poses.end()))}};
}

json ViewerState::TileJson(const Tile& tile) {
  return {{"x", tile.x},
          {"y", tile.y},
          {"w", tile.width},
          {"h", tile.height},
          {"res", tile.resolution_m},
          {"update", tile.update},
          {"cells",
           Base64Encode(reinterpret_cast<const uint8_t*>(tile.cells.data()), tile.cells.size())}};
}

json ViewerState::StatusJson() const { return status_; }

json ViewerState::TakeDelta() {
  ++seq_;
  json delta = {{"type", "delta"},         {"seq", seq_},
                {"restarts", restarts_},   {"map_update", map_update_},
                {"map_utime", map_utime_}, {"wall_utime", last_message_wall_utime_},
                {"removed", removed_},     {"clear_tiles", tiles_cleared_}};
  json trajectories = json::array();
  for (auto& [key, t] : trajectories_) {
    if (t.first_changed == kUnchanged) continue;
    trajectories.push_back(TrajectoryJson(key, t, t.first_changed));
    t.first_changed = kUnchanged;
  }
  delta["trajectories"] = std::move(trajectories);
  if (encounters_first_changed_ != kUnchanged) {
    const size_t from = std::min(encounters_first_changed_, encounters_.size());
    delta["encounters"] = {
        {"from", from},
        {"links", std::vector<json>(encounters_.begin() + static_cast<std::ptrdiff_t>(from),
                                    encounters_.end())}};
  }
  json tiles = json::array();
  for (auto& [key, t] : tiles_) {
    if (!t.changed) continue;
    tiles.push_back(TileJson(t));
    t.changed = false;
  }
  delta["tiles"] = std::move(tiles);
  // A tile dropped and then brought again within one delta is in both: removals first.
  delta["removed_tiles"] = removed_tiles_;
  removed_tiles_.clear();
  if (covariances_changed_) delta["covariances"] = covariances_;
  if (status_changed_) delta["status"] = status_;
  removed_.clear();
  encounters_first_changed_ = kUnchanged;
  tiles_cleared_ = false;
  covariances_changed_ = false;
  status_changed_ = false;
  meta_changed_ = false;
  return delta;
}

json ViewerState::Full() const {
  json full = {{"type", "full"},           {"seq", seq_},
               {"restarts", restarts_},    {"map_update", map_update_},
               {"map_utime", map_utime_},  {"wall_utime", last_message_wall_utime_},
               {"removed", json::array()}, {"clear_tiles", true}};
  json trajectories = json::array();
  for (const auto& [key, t] : trajectories_) trajectories.push_back(TrajectoryJson(key, t, 0));
  full["trajectories"] = std::move(trajectories);
  full["encounters"] = {{"from", 0}, {"links", encounters_}};
  json tiles = json::array();
  for (const auto& [key, t] : tiles_) tiles.push_back(TileJson(t));
  full["tiles"] = std::move(tiles);
  full["removed_tiles"] = json::array();
  full["covariances"] = covariances_;
  full["status"] = status_;
  return full;
}

}  // namespace anchormap::viewer
