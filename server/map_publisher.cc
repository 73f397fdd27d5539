#include "server/map_publisher.h"

#include <map>

namespace anchormap {

MergedMap MapPublisher::BuildMergedMap(const Smoother& smoother, const TrajectoryTable& table,
                                       const std::vector<EncounterLink>& links, int64_t utime,
                                       int64_t update) const {
  MergedMap map;
  map.utime = utime;
  map.update = update;
  for (const TrajectoryRecord& record : table.records()) {
    if (record.num_keyframes() == 0 || smoother.NumPoses(record.solver_id) == 0) continue;
    MergedTrajectory t;
    t.robot = record.robot;
    t.trajectory_id = record.agent_trajectory_id;
    t.anchored = smoother.IsAnchored(record.solver_id);
    if (const auto anchor = smoother.Anchor(record.solver_id)) t.T_global_local = *anchor;
    t.poses = smoother.GlobalTrajectory(record.solver_id);
    t.pose_utimes.assign(record.utimes.begin(),
                         record.utimes.begin() + static_cast<long>(t.poses.size()));
    map.trajectories.push_back(std::move(t));
  }
  map.encounters = links;
  return map;
}

AnchorCovariances MapPublisher::BuildAnchorCovariances(Smoother* smoother,
                                                       const TrajectoryTable& table, int64_t utime,
                                                       int64_t update) const {
  AnchorCovariances out;
  out.utime = utime;
  out.update = update;
  for (const TrajectoryRecord& record : table.records()) {
    const auto anchor = smoother->Anchor(record.solver_id);
    if (!anchor || !smoother->HasCovariance(Key(AnchorKey{record.solver_id}))) continue;
    AnchorCovariance a;
    a.robot = record.robot;
    a.trajectory_id = record.agent_trajectory_id;
    a.T_global_local = *anchor;
    a.covariance = smoother->MarginalCovariance(Key(AnchorKey{record.solver_id}));
    out.anchors.push_back(a);
  }
  return out;
}

std::vector<TrajectoryId> MapPublisher::GridTrajectories(const Smoother& smoother,
                                                         const TrajectoryTable& table) const {
  std::map<TrajectoryId, int64_t> keyframes_per_group;
  for (const TrajectoryRecord& record : table.records()) {
    if (smoother.NumPoses(record.solver_id) == 0) continue;
    keyframes_per_group[smoother.GroupRoot(record.solver_id)] += record.num_keyframes();
  }
  if (keyframes_per_group.empty()) return {};
  TrajectoryId best_root = keyframes_per_group.begin()->first;
  for (const auto& [root, count] : keyframes_per_group) {
    if (count > keyframes_per_group[best_root]) best_root = root;
  }
  std::vector<TrajectoryId> members;
  for (const TrajectoryRecord& record : table.records()) {
    if (smoother.NumPoses(record.solver_id) > 0 &&
        smoother.GroupRoot(record.solver_id) == best_root) {
      members.push_back(record.solver_id);
    }
  }
  return members;
}

std::vector<GridTile> MapPublisher::BuildGridTiles(const Smoother& smoother,
                                                   const TrajectoryTable& table, int64_t utime,
                                                   int64_t update) const {
  OccupancyGrid grid(options_.grid);
  for (TrajectoryId id : GridTrajectories(smoother, table)) {
    const TrajectoryRecord* record = table.FindBySolverId(id);
    const std::vector<Pose2> poses = smoother.GlobalTrajectory(id);
    for (size_t i = 0; i < poses.size() && i < record->scans.size(); ++i) {
      grid.InsertScan(record->scans[i], poses[i]);
    }
  }
  return grid.Tiles(utime, update);
}

bool MapPublisher::MapDue(int64_t now_utime, int64_t update) const {
  if (update <= last_map_update_) return false;
  return !last_map_utime_ ||
         1e-6 * static_cast<double>(now_utime - *last_map_utime_) >= options_.map_period_s;
}

void MapPublisher::MarkMapPublished(int64_t now_utime, int64_t update) {
  last_map_utime_ = now_utime;
  last_map_update_ = update;
}

bool MapPublisher::GridDue(int64_t now_utime, int64_t update) const {
  if (options_.grid_period_s <= 0 || update <= last_grid_update_) return false;
  return !last_grid_utime_ ||
         1e-6 * static_cast<double>(now_utime - *last_grid_utime_) >= options_.grid_period_s;
}

void MapPublisher::MarkGridPublished(int64_t now_utime, int64_t update) {
  last_grid_utime_ = now_utime;
  last_grid_update_ = update;
}

}  // namespace anchormap
