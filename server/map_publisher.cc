#include "server/map_publisher.h"

#include <algorithm>
#include <map>
#include <optional>
#include <unordered_set>

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

double MapPublisher::Refresh(int64_t now_utime, bool* full) {
  // The time since the last map over map_full_period_s, so that every chunk goes out about
  // once per period, a few at each map rather than all at once (all of them on the first
  // map, or with a period of 0).
  double refresh = 1.0;
  if (last_map_split_utime_ && options_.map_full_period_s > 0) {
    refresh =
        1e-6 * static_cast<double>(now_utime - *last_map_split_utime_) / options_.map_full_period_s;
  }
  last_map_split_utime_ = now_utime;
  *full = *full || refresh >= 1.0;
  return refresh;
}

MapChunker::Split MapPublisher::SplitMergedMap(const Smoother& smoother,
                                               const TrajectoryTable& table,
                                               const std::vector<EncounterLink>& links,
                                               int64_t utime, int64_t update, int64_t now_utime,
                                               bool full) {
  // BuildMergedMap's trajectories, their poses in their local frames: the smoother's own
  // (relative formulation, or not anchored: the frame is the global one), else the global
  // frame's made local by the anchor.
  const bool relative = smoother.options().formulation == Formulation::kRelative;
  std::vector<MapChunker::Trajectory> trajectories;
  for (const TrajectoryRecord& record : table.records()) {
    const int poses = smoother.NumPoses(record.solver_id);
    if (record.num_keyframes() == 0 || poses == 0) continue;
    MapChunker::Trajectory t;
    t.robot = record.robot;
    t.trajectory_id = record.agent_trajectory_id;
    t.anchored = smoother.IsAnchored(record.solver_id);
    if (const auto anchor = smoother.Anchor(record.solver_id)) t.T_global_local = *anchor;
    t.num_poses = poses;
    t.pose_utimes = &record.utimes;
    const TrajectoryId id = record.solver_id;
    const bool frame_is_local = relative || !t.anchored;
    const Pose2 T_local_global = t.T_global_local.Inverse();
    t.local_poses = [&smoother, id, frame_is_local, T_local_global](int64_t first, int64_t end,
                                                                    Pose2* out) {
      for (int64_t i = first; i < end; ++i) {
        const Pose2 pose = smoother.FramePose(PoseKey{id, static_cast<int32_t>(i)});
        out[i - first] = frame_is_local ? pose : Compose(T_local_global, pose);
      }
    };
    trajectories.push_back(std::move(t));
  }
  const double refresh = Refresh(now_utime, &full);
  return chunker_.Update(utime, update, trajectories, links, full, refresh);
}

AnchorCovariances MapPublisher::BuildAnchorCovariances(Smoother* smoother,
                                                       const TrajectoryTable& table, int64_t utime,
                                                       int64_t update) const {
  AnchorCovariances out;
  out.utime = utime;
  out.update = update;
  std::vector<Key> anchors;
  for (const TrajectoryId trajectory : PublishedAnchors(*smoother, table)) {
    const TrajectoryRecord& record = *table.FindBySolverId(trajectory);
    AnchorCovariance a;
    a.robot = record.robot;
    a.trajectory_id = record.agent_trajectory_id;
    a.T_global_local = *smoother->Anchor(trajectory);
    out.anchors.push_back(a);
    anchors.push_back(Key(AnchorKey{trajectory}));
  }
  // One sparse solve per anchor (J = I: the marginal itself), which reads R's rows below
  // the anchor. The block recursion (MarginalCovariance) computed every pair of the dense
  // corner that anchors and latest poses form at the bottom of R, its cube: 8 % of a
  // 100-robot replay's samples at 90-120 s of data. The same values up to round-off. The
  // anchors' solves run side by side (ProjectedMarginals, each its own bits): their paths
  // share most of R's wide bottom rows, read once instead of once per anchor.
  const std::vector<Eigen::Matrix3d> covariances = smoother->ProjectedMarginals(anchors);
  for (size_t i = 0; i < anchors.size(); ++i) {
    out.anchors[i].covariance = 0.5 * (covariances[i] + covariances[i].transpose());
  }
  return out;
}

std::vector<TrajectoryId> MapPublisher::PublishedAnchors(const Smoother& smoother,
                                                         const TrajectoryTable& table) const {
  std::vector<TrajectoryId> out;
  for (const TrajectoryRecord& record : table.records()) {
    // Between updates (solve_period_s) an anchor is published once solved.
    if (smoother.Anchor(record.solver_id) && smoother.IsSolved(Key(AnchorKey{record.solver_id}))) {
      out.push_back(record.solver_id);
    }
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

namespace {
// A keyframe's key in the grid: its solver trajectory and index.
uint64_t GridKey(TrajectoryId trajectory, size_t index) {
  return (static_cast<uint64_t>(trajectory.value()) << 32) | static_cast<uint64_t>(index);
}
}  // namespace

MapPublisher::GridChange MapPublisher::UpdateGrid(const Smoother& smoother,
                                                  const TrajectoryTable& table, bool complete) {
  GridChange change;
  std::unordered_set<uint64_t> current;
  // Placed keyframes that moved past the tolerance: (displacement, key, scan, pose).
  struct Moved {
    double displacement;
    uint64_t key;
    const LaserScan* scan;
    Pose2 pose;
  };
  std::vector<Moved> moved;
  std::vector<KeyframeGrid::Keyframe> inserted;
  // When complete: the placed keyframes that stay where they were traced (a rebuild's).
  std::vector<KeyframeGrid::Keyframe> unchanged;
  for (TrajectoryId id : GridTrajectories(smoother, table)) {
    const TrajectoryRecord* record = table.FindBySolverId(id);
    const std::vector<Pose2> poses = smoother.GlobalTrajectory(id);
    for (size_t i = 0; i < poses.size() && i < record->scans.size(); ++i) {
      const uint64_t key = GridKey(id, i);
      current.insert(key);
      const std::optional<double> displacement = grid_.Displacement(key, poses[i]);
      if (!displacement) {
        inserted.push_back({key, &record->scans[i], poses[i]});
      } else if (*displacement > grid_.move_tolerance_m()) {
        moved.push_back({*displacement, key, &record->scans[i], poses[i]});
      } else if (complete) {
        unchanged.push_back({key, &record->scans[i], grid_.placed().at(key)});
      }
    }
  }
  change.inserted = static_cast<int64_t>(inserted.size());
  // Keyframes of trajectories that left the grid's group (the largest group changed), with
  // their scans (nullptr: none known, the keyframe stays).
  std::vector<std::pair<uint64_t, const LaserScan*>> gone;
  bool gone_known = true;
  for (const auto& [key, pose] : grid_.placed()) {
    if (current.count(key) != 0) continue;
    const TrajectoryRecord* record =
        table.FindBySolverId(TrajectoryId(static_cast<int64_t>(key >> 32)));
    const size_t index = key & 0xffffffffu;
    const bool known = record != nullptr && index < record->scans.size();
    gone.push_back({key, known ? &record->scans[index] : nullptr});
    gone_known = gone_known && known;
  }
  // A complete grid where most placed keyframes moved is cheaper made again: one trace per
  // keyframe instead of two per move (the end of a 100-robot run moves nearly all of them).
  if (complete && gone_known && moved.size() + gone.size() > unchanged.size()) {
    std::vector<KeyframeGrid::Keyframe> keyframes = std::move(unchanged);
    for (const Moved& m : moved) keyframes.push_back({m.key, m.scan, m.pose});
    keyframes.insert(keyframes.end(), inserted.begin(), inserted.end());
    grid_.Rebuild(keyframes);
    change.moved = static_cast<int64_t>(moved.size());
    change.removed = static_cast<int64_t>(gone.size());
    return change;
  }
  for (const KeyframeGrid::Keyframe& keyframe : inserted) {
    grid_.Place(keyframe.key, *keyframe.scan, keyframe.T_map_body);
  }
  // The farthest moved first; ties by key (trajectory, index): deterministic.
  size_t take = moved.size();
  if (!complete && options_.grid_max_moved > 0) {
    const double budget =
        std::min(static_cast<double>(options_.grid_max_moved),
                 options_.grid_min_moved +
                     options_.grid_moved_per_inserted * static_cast<double>(change.inserted));
    take = std::min(take, static_cast<size_t>(budget));
    std::stable_sort(moved.begin(), moved.end(), [](const Moved& a, const Moved& b) {
      return a.displacement > b.displacement;
    });
  }
  for (size_t n = 0; n < take; ++n) {
    if (grid_.Place(moved[n].key, *moved[n].scan, moved[n].pose) ==
        KeyframeGrid::Placement::kMoved) {
      ++change.moved;
    }
  }
  change.deferred = static_cast<int64_t>(moved.size() - take);
  for (const auto& [key, scan] : gone) {
    if (scan != nullptr && grid_.Remove(key, *scan)) ++change.removed;
  }
  return change;
}

std::vector<GridTile> MapPublisher::BuildGridTiles(const Smoother& smoother,
                                                   const TrajectoryTable& table, int64_t utime,
                                                   int64_t update, bool complete) {
  UpdateGrid(smoother, table, complete);
  grid_.ForgetChanges();
  return grid_.Tiles(utime, update);
}

std::vector<GridTile> MapPublisher::BuildChangedGridTiles(const Smoother& smoother,
                                                          const TrajectoryTable& table,
                                                          int64_t utime, int64_t update) {
  UpdateGrid(smoother, table);
  return grid_.TakeChangedTiles(utime, update);
}

bool MapPublisher::MapDue(int64_t now_utime, int64_t update) const {
  if (update <= last_map_update_) return false;
  return !last_map_utime_ ||
         1e-6 * static_cast<double>(now_utime - *last_map_utime_) >= options_.map_period_s;
}

bool MapPublisher::AnchorCovariancesDue(int64_t now_utime, const std::vector<TrajectoryId>& anchors,
                                        bool full) const {
  return full || !last_covariances_utime_ || anchors != last_covariances_anchors_ ||
         1e-6 * static_cast<double>(now_utime - *last_covariances_utime_) >=
             options_.anchor_covariances_period_s;
}

void MapPublisher::MarkAnchorCovariancesPublished(int64_t now_utime,
                                                  std::vector<TrajectoryId> anchors) {
  last_covariances_utime_ = now_utime;
  last_covariances_anchors_ = std::move(anchors);
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

bool MapPublisher::GridFullDue(int64_t now_utime) const {
  return !last_grid_full_utime_ || 1e-6 * static_cast<double>(now_utime - *last_grid_full_utime_) >=
                                       options_.grid_full_period_s;
}

void MapPublisher::MarkGridPublished(int64_t now_utime, int64_t update) {
  last_grid_utime_ = now_utime;
  last_grid_update_ = update;
}

}  // namespace anchormap
