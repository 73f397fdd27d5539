#include "server/map_chunker.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include "common/geometry/angle.h"

namespace anchormap {

bool MapChunker::Rewritten(const MergedMapChunk& sent, const MergedMapChunk& now) {
  return sent.local_poses.size() != now.local_poses.size() || sent.pose_utimes != now.pose_utimes ||
         sent.encounter_positions != now.encounter_positions || sent.encounters != now.encounters;
}

namespace {
// A difference in tolerances: 0 within it.
double Excess(double difference, double tolerance) {
  if (difference <= tolerance) return 0.0;
  return tolerance > 0.0 ? difference / tolerance : std::numeric_limits<double>::infinity();
}
}  // namespace

double MapChunker::Moved(const MergedMapChunk& sent, const MergedMapChunk& now) const {
  double moved = 0.0;
  for (size_t i = 0; i < now.local_poses.size(); ++i) {
    const Pose2& a = sent.local_poses[i];
    const Pose2& b = now.local_poses[i];
    moved =
        std::max({moved, Excess(std::abs(a.x() - b.x()), options_.tolerance_m),
                  Excess(std::abs(a.y() - b.y()), options_.tolerance_m),
                  Excess(std::abs(AngleDifference(a.theta(), b.theta())), options_.tolerance_rad)});
  }
  return moved;
}

MapChunker::Split MapChunker::Update(const MergedMap& map, bool full, double refresh) {
  const int64_t size = options_.chunk_poses;
  Split out;
  out.header.utime = map.utime;
  out.header.update = map.update;
  out.header.chunk_poses = options_.chunk_poses;
  // Every chunk's current content, poses first.
  std::map<ChunkId, MergedMapChunk> now;
  std::map<std::pair<std::string, int64_t>, const MergedTrajectory*> by_name;
  for (const MergedTrajectory& t : map.trajectories) {
    by_name[{t.robot, t.trajectory_id}] = &t;
    const Pose2 T_local_global = t.T_global_local.Inverse();
    const CosSin rotation = CosSin::Of(T_local_global.theta());  // once per trajectory
    const auto poses = static_cast<int64_t>(t.poses.size());
    for (int64_t first = 0; first < poses; first += size) {
      MergedMapChunk chunk;
      chunk.utime = map.utime;
      chunk.robot = t.robot;
      chunk.trajectory_id = t.trajectory_id;
      chunk.chunk_index = static_cast<int32_t>(first / size);
      const int64_t end = std::min(poses, first + size);
      for (int64_t i = first; i < end; ++i) {
        chunk.local_poses.push_back(
            Compose(T_local_global, rotation, t.poses[static_cast<size_t>(i)]));
        chunk.pose_utimes.push_back(i < static_cast<int64_t>(t.pose_utimes.size())
                                        ? t.pose_utimes[static_cast<size_t>(i)]
                                        : 0);
      }
      now.emplace(ChunkId{t.robot, t.trajectory_id, chunk.chunk_index}, std::move(chunk));
    }
  }
  // Each encounter in the chunk of its second keyframe, else of its first; one that joins
  // no keyframe of the map has no chunk and is left out (the header counts the others).
  int32_t placed = 0;
  for (size_t e = 0; e < map.encounters.size(); ++e) {
    const EncounterLink& link = map.encounters[e];
    for (const auto& [robot, trajectory, index] :
         {std::tuple(link.robot_b, link.trajectory_b, link.index_b),
          std::tuple(link.robot_a, link.trajectory_a, link.index_a)}) {
      const auto it = by_name.find({robot, trajectory});
      if (it == by_name.end() || index < 0 ||
          index >= static_cast<int64_t>(it->second->poses.size())) {
        continue;
      }
      MergedMapChunk& chunk =
          now.at(ChunkId{robot, trajectory, static_cast<int32_t>(index / size)});
      chunk.encounters.push_back(link);
      chunk.encounter_positions.push_back(placed++);
      break;
    }
  }
  out.header.num_encounters = placed;
  // The chunks to send get this update as their version; the others keep theirs.
  using Entry = std::map<ChunkId, MergedMapChunk>::iterator;
  std::vector<Entry> send;
  std::vector<std::pair<double, Entry>> moved;  // (how far, chunk), in the map's order
  std::vector<std::pair<int64_t, Entry>> kept;  // (version sent, chunk), in the map's order
  for (auto it = now.begin(); it != now.end(); ++it) {
    const auto sent = sent_.find(it->first);
    if (full || sent == sent_.end() || Rewritten(sent->second, it->second)) {
      send.push_back(it);
      continue;
    }
    it->second.version = sent->second.version;
    const double how_far = Moved(sent->second, it->second);
    if (how_far > 0.0) {
      moved.emplace_back(how_far, it);
    } else {
      kept.emplace_back(it->second.version, it);
    }
  }
  // The farthest moved first, within the budget; the others wait like unmoved chunks.
  std::stable_sort(moved.begin(), moved.end(),
                   [](const auto& a, const auto& b) { return a.first > b.first; });
  const size_t budget =
      options_.max_moved_chunks > 0 ? static_cast<size_t>(options_.max_moved_chunks) : moved.size();
  for (size_t i = 0; i < moved.size(); ++i) {
    if (i < budget) {
      send.push_back(moved[i].second);
    } else {
      kept.emplace_back(moved[i].second->second.version, moved[i].second);
    }
  }
  // The refresh: the least recently sent first, ties in the map's order.
  std::stable_sort(kept.begin(), kept.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first < b.first : a.second->first < b.second->first;
  });
  const auto refreshed =
      std::min(kept.size(), static_cast<size_t>(std::ceil(std::clamp(refresh, 0.0, 1.0) *
                                                          static_cast<double>(now.size()))));
  for (size_t i = 0; i < refreshed; ++i) send.push_back(kept[i].second);
  // Sent in the map's order.
  std::sort(send.begin(), send.end(),
            [](const Entry& a, const Entry& b) { return a->first < b->first; });
  for (const Entry& it : send) {
    it->second.version = map.update;
    out.chunks.push_back(it->second);
    sent_[it->first] = std::move(it->second);
  }
  // Chunks that no longer exist (a trajectory lost keyframes: a server restart) are forgotten.
  for (auto it = sent_.begin(); it != sent_.end();) {
    it = now.count(it->first) ? std::next(it) : sent_.erase(it);
  }
  for (const MergedTrajectory& t : map.trajectories) {
    MergedMapHeader::Trajectory h;
    h.robot = t.robot;
    h.trajectory_id = t.trajectory_id;
    h.anchored = t.anchored;
    h.T_global_local = t.T_global_local;
    h.num_poses = static_cast<int32_t>(t.poses.size());
    for (int32_t k = 0; static_cast<int64_t>(k) * size < h.num_poses; ++k) {
      h.chunk_versions.push_back(sent_.at(ChunkId{t.robot, t.trajectory_id, k}).version);
    }
    out.header.trajectories.push_back(std::move(h));
  }
  return out;
}

}  // namespace anchormap
