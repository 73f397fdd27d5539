#include "server/map_publisher.h"

#include <algorithm>
#include <map>
#include <optional>
#include <unordered_map>
#include <unordered_set>
#include <utility>

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

namespace {
// A pose key in 64 bits (solver trajectory and index, both within 32 bits): a keyframe's key
// in the grid and a node's id in KeyframeMoves; and back.
uint64_t PackedKey(PoseKey key) {
  return (static_cast<uint64_t>(key.trajectory.value()) << 32) |
         static_cast<uint64_t>(static_cast<uint32_t>(key.index));
}
PoseKey UnpackedKey(uint64_t packed) {
  return PoseKey{TrajectoryId(static_cast<int64_t>(packed >> 32)),
                 static_cast<int32_t>(packed & 0xffffffffu)};
}
}  // namespace

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
    // Each keyframe as its node (+) its offset (an alias), or its own node; the node's pose
    // in this frame: FramePose's for an alias of the trajectory's own node, else
    // Between(anchor, GlobalPose(node)) (an alias of another trajectory's node: FramePose
    // is Between(anchor, GlobalPose(node) (+) offset)), made local as above.
    t.node_of = [&smoother, id](int64_t index) {
      const PoseKey key{id, static_cast<int32_t>(index)};
      const PoseAlias* alias = smoother.FindAlias(key);
      MapChunker::Trajectory::NodeOffset node;
      node.node = PackedKey(alias != nullptr ? alias->node : key);
      if (alias != nullptr) node.T_node_key = alias->T_node_key;
      return node;
    };
    const std::optional<Pose2> anchor = smoother.Anchor(id);
    t.node_pose = [&smoother, id, relative, anchor, frame_is_local, T_local_global](uint64_t n) {
      const PoseKey node = UnpackedKey(n);
      const Pose2 pose = relative && node.trajectory != id
                             ? Between(*anchor, smoother.GlobalPose(node))
                             : smoother.FramePose(node);
      return frame_is_local ? pose : Compose(T_local_global, pose);
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

MapPublisher::GridChange MapPublisher::UpdateGrid(const Smoother& smoother,
                                                  const TrajectoryTable& table, bool complete) {
  const GridChange change = MoveGrid(smoother, table, complete);
  ++grid_work_.updates;
  grid_work_.inserted += change.inserted;
  grid_work_.moved += change.moved;
  grid_work_.deferred += change.deferred;
  grid_work_.removed += change.removed;
  return change;
}

std::string MapPublisher::WorkSummary() const {
  const GridWork& g = grid_work_;
  const MapChunker::Work& c = chunker_.work();
  return "grid work: updates " + std::to_string(g.updates) + " inserted " +
         std::to_string(g.inserted) + " moved " + std::to_string(g.moved) + " deferred " +
         std::to_string(g.deferred) + " removed " + std::to_string(g.removed) + " rebuilds " +
         std::to_string(g.rebuilds) + " nodes_examined " + std::to_string(g.nodes_examined) +
         " moves_found " + std::to_string(g.moves_found) + "; chunk work: updates " +
         std::to_string(c.updates) + " chunks " + std::to_string(c.chunks) + " read " +
         std::to_string(c.read) + " moved " + std::to_string(c.moved) + " sent " +
         std::to_string(c.sent) + " nodes_examined " + std::to_string(c.nodes_examined);
}

MapPublisher::GridChange MapPublisher::MoveGrid(const Smoother& smoother,
                                                const TrajectoryTable& table, bool complete) {
  GridChange change;
  // The grid's trajectories, each with its place in the table (the keyframes' order) and
  // how many keyframes it holds (a pose and a scan).
  const std::vector<TrajectoryId> trajectories = GridTrajectories(smoother, table);
  std::unordered_map<int64_t, uint64_t> table_index;
  for (size_t r = 0; r < table.records().size(); ++r) {
    table_index[table.records()[r].solver_id.value()] = r;
  }
  std::vector<int32_t> counts(trajectories.size(), 0);
  bool reset = false;
  for (size_t t = 0; t < trajectories.size(); ++t) {
    const TrajectoryId id = trajectories[t];
    const auto scans = static_cast<int64_t>(table.FindBySolverId(id)->scans.size());
    const auto known = grid_counts_.find(id.value());
    int32_t count = known != grid_counts_.end() ? known->second : 0;
    if (count > scans || (count > 0 && !smoother.HasPose(PoseKey{id, count - 1}))) {
      reset = true;  // a restarted trajectory: counted again below
      count = 0;
    }
    while (count < scans && smoother.HasPose(PoseKey{id, count})) ++count;
    counts[t] = count;
  }
  // A trajectory left the grid's group (the largest group changed): its keyframes go, with
  // their scans (nullptr: none known, the keyframe stays); the moves are found afresh.
  // A trajectory that joined only adds keyframes.
  std::unordered_set<int64_t> current;
  for (const TrajectoryId id : trajectories) current.insert(id.value());
  for (const auto& [id, count] : grid_counts_) reset = reset || current.count(id) == 0;
  std::vector<std::pair<uint64_t, const LaserScan*>> gone;
  bool gone_known = true;
  if (reset) {
    moves_.Clear();
    grid_counts_.clear();
    std::unordered_map<int64_t, int32_t> holds;
    for (size_t t = 0; t < trajectories.size(); ++t) holds[trajectories[t].value()] = counts[t];
    for (const auto& [key, pose] : grid_.placed()) {
      const PoseKey placed = UnpackedKey(key);
      const size_t index = static_cast<size_t>(placed.index);
      const auto it = holds.find(placed.trajectory.value());
      if (it != holds.end() && index < static_cast<size_t>(it->second)) continue;
      const TrajectoryRecord* record = table.FindBySolverId(placed.trajectory);
      const bool known = record != nullptr && index < record->scans.size();
      gone.push_back({key, known ? &record->scans[index] : nullptr});
      gone_known = gone_known && known;
    }
  }
  // The keyframes new to the moves: each its node's pose (+) its offset (an alias), or
  // its own variable; ordered by their trajectory's place in the table, then index.
  for (size_t t = 0; t < trajectories.size(); ++t) {
    const TrajectoryId id = trajectories[t];
    const TrajectoryRecord* record = table.FindBySolverId(id);
    const uint64_t rank = table_index.at(id.value());
    int32_t& held = grid_counts_[id.value()];
    for (int32_t i = held; i < counts[t]; ++i) {
      const PoseKey key{id, i};
      const PoseAlias* alias = smoother.FindAlias(key);
      const PoseKey node = alias != nullptr ? alias->node : key;
      const uint64_t grid_key = PackedKey(key);
      const std::optional<double> reach = grid_.Reach(grid_key);
      moves_.Add(grid_key, (rank << 32) | static_cast<uint64_t>(i), PackedKey(node),
                 alias != nullptr ? std::optional<Pose2>(alias->T_node_key) : std::nullopt,
                 (alias != nullptr ? alias->T_node_key.translation().norm() : 0.0) +
                     (reach ? *reach : grid_.ReachFromBody(record->scans[static_cast<size_t>(i)])),
                 reach.has_value());
    }
    held = counts[t];
  }
  std::unordered_map<int64_t, std::optional<Pose2>> anchors;  // by trajectory
  KeyframeMoves::Pass pass = moves_.Examine(
      [&smoother, &anchors](uint64_t node) {
        // Smoother::GlobalPose's bits with each trajectory's anchor looked up once.
        const PoseKey key = UnpackedKey(node);
        auto [it, is_new] = anchors.try_emplace(key.trajectory.value());
        if (is_new && smoother.options().formulation == Formulation::kRelative) {
          it->second = smoother.Anchor(key.trajectory);
        }
        const Pose2 pose = smoother.FramePose(key);
        return it->second ? Compose(*it->second, pose) : pose;
      },
      [this](uint64_t key, const Pose2& pose) { return grid_.Displacement(key, pose); }, complete);
  grid_work_.nodes_examined += pass.nodes_examined;
  grid_work_.moves_found += static_cast<int64_t>(pass.moved.size());
  const auto scan_of = [&](uint64_t order) {
    return &table.records()[order >> 32].scans[order & 0xffffffffu];
  };
  // In the order of the grid's trajectories and their indices, the farthest moved first.
  const auto by_order = [](const KeyframeMoves::Found& a, const KeyframeMoves::Found& b) {
    return a.order < b.order;
  };
  std::sort(pass.unchanged.begin(), pass.unchanged.end(), by_order);
  std::sort(pass.moved.begin(), pass.moved.end(),
            [](const KeyframeMoves::Found& a, const KeyframeMoves::Found& b) {
              return a.displacement > b.displacement ||
                     (a.displacement == b.displacement && a.order < b.order);
            });
  change.inserted = static_cast<int64_t>(pass.inserted.size());
  // A complete grid where most placed keyframes moved is cheaper made again: one trace per
  // keyframe instead of two per move (the end of a 100-robot run moves nearly all of them).
  if (complete && gone_known && pass.moved.size() + gone.size() > pass.unchanged.size()) {
    std::vector<KeyframeGrid::Keyframe> keyframes;
    for (const KeyframeMoves::Found& f : pass.unchanged) {
      keyframes.push_back({f.key, scan_of(f.order), grid_.placed().at(f.key)});
    }
    std::sort(pass.moved.begin(), pass.moved.end(), by_order);
    for (const KeyframeMoves::Found& f : pass.moved) {
      keyframes.push_back({f.key, scan_of(f.order), f.pose});
    }
    for (const KeyframeMoves::Found& f : pass.inserted) {
      keyframes.push_back({f.key, scan_of(f.order), f.pose});
    }
    grid_.Rebuild(keyframes);
    ++grid_work_.rebuilds;
    moves_.Settle({});
    change.moved = static_cast<int64_t>(pass.moved.size());
    change.removed = static_cast<int64_t>(gone.size());
    return change;
  }
  for (const KeyframeMoves::Found& f : pass.inserted) grid_.Place(f.key, *scan_of(f.order), f.pose);
  size_t take = pass.moved.size();
  if (!complete && options_.grid_max_moved > 0) {
    const double budget =
        std::min(static_cast<double>(options_.grid_max_moved),
                 options_.grid_min_moved +
                     options_.grid_moved_per_inserted * static_cast<double>(change.inserted));
    take = std::min(take, static_cast<size_t>(budget));
  }
  for (size_t n = 0; n < take; ++n) {
    const KeyframeMoves::Found& f = pass.moved[n];
    if (grid_.Place(f.key, *scan_of(f.order), f.pose) == KeyframeGrid::Placement::kMoved) {
      ++change.moved;
    }
  }
  change.deferred = static_cast<int64_t>(pass.moved.size() - take);
  moves_.Settle(std::vector<KeyframeMoves::Found>(
      pass.moved.begin() + static_cast<std::ptrdiff_t>(take), pass.moved.end()));
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
