#include "server/map_chunker.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string_view>
#include <unordered_map>
#include <utility>

#include "common/geometry/angle.h"

namespace anchormap {

namespace {
struct NameHash {
  size_t operator()(const std::pair<std::string_view, int64_t>& name) const {
    return std::hash<std::string_view>()(name.first) ^
           (std::hash<int64_t>()(name.second) * size_t{0x9e3779b97f4a7c15u});
  }
};

// A difference in tolerances: 0 within it.
double Excess(double difference, double tolerance) {
  if (difference <= tolerance) return 0.0;
  return tolerance > 0.0 ? difference / tolerance : std::numeric_limits<double>::infinity();
}
}  // namespace

double MapChunker::Moved(const std::vector<Pose2>& sent, const std::vector<Pose2>& now) const {
  double moved = 0.0;
  for (size_t i = 0; i < now.size(); ++i) {
    const Pose2& a = sent[i];
    const Pose2& b = now[i];
    moved =
        std::max({moved, Excess(std::abs(a.x() - b.x()), options_.tolerance_m),
                  Excess(std::abs(a.y() - b.y()), options_.tolerance_m),
                  Excess(std::abs(AngleDifference(a.theta(), b.theta())), options_.tolerance_rad)});
  }
  return moved;
}

double MapChunker::Measure(const Pose2& a, const Pose2& b) const {
  return std::max({std::abs(a.x() - b.x()) / options_.tolerance_m,
                   std::abs(a.y() - b.y()) / options_.tolerance_m,
                   std::abs(AngleDifference(a.theta(), b.theta())) / options_.tolerance_rad});
}

MapChunker::Split MapChunker::Update(const MergedMap& map, bool full, double refresh) {
  std::vector<Trajectory> trajectories;
  trajectories.reserve(map.trajectories.size());
  for (const MergedTrajectory& t : map.trajectories) {
    Trajectory view;
    view.robot = t.robot;
    view.trajectory_id = t.trajectory_id;
    view.anchored = t.anchored;
    view.T_global_local = t.T_global_local;
    view.num_poses = static_cast<int64_t>(t.poses.size());
    view.pose_utimes = &t.pose_utimes;
    const Pose2 T_local_global = t.T_global_local.Inverse();
    const CosSin rotation = CosSin::Of(T_local_global.theta());  // once per trajectory
    view.local_poses = [&t, T_local_global, rotation](int64_t first, int64_t end, Pose2* out) {
      for (int64_t i = first; i < end; ++i) {
        out[i - first] = Compose(T_local_global, rotation, t.poses[static_cast<size_t>(i)]);
      }
    };
    trajectories.push_back(std::move(view));
  }
  return Update(map.utime, map.update, trajectories, map.encounters, full, refresh);
}

MapChunker::Split MapChunker::Update(int64_t utime, int64_t update,
                                     const std::vector<Trajectory>& trajectories,
                                     const std::vector<EncounterLink>& encounters, bool full,
                                     double refresh) {
  const int64_t size = options_.chunk_poses;
  Split out;
  out.header.utime = utime;
  out.header.update = update;
  out.header.chunk_poses = options_.chunk_poses;
  // Every chunk of the map, numbered trajectory by trajectory (chunk k of trajectory t is
  // chunk first_chunk[t] + k), then put in the order robot, trajectory, index.
  // Hashed: every encounter is looked up here at every update (11.8k at the end of 20 x 1800
  // with the option), and a tree's string comparisons grew with them (late27).
  std::unordered_map<std::pair<std::string_view, int64_t>, size_t, NameHash> by_name;
  std::vector<int64_t> first_chunk;
  int64_t num_chunks = 0;
  for (size_t t = 0; t < trajectories.size(); ++t) {
    by_name[{trajectories[t].robot, trajectories[t].trajectory_id}] = t;
    first_chunk.push_back(num_chunks);
    num_chunks += (trajectories[t].num_poses + size - 1) / size;
  }
  // Each encounter in the chunk of its second keyframe, else of its first; one that joins
  // no keyframe of the map has no chunk and is left out (the header counts the others). By
  // chunk, [link_begin[c], link_begin[c + 1]) of link_index (the encounter) and
  // link_position (its position among those placed): indices, no copies of the links.
  const auto chunk_of = [&](const std::string& robot, int64_t trajectory, int32_t index) {
    const auto it = by_name.find({robot, trajectory});
    if (it == by_name.end() || index < 0 || index >= trajectories[it->second].num_poses) {
      return int64_t{-1};
    }
    return first_chunk[it->second] + index / size;
  };
  std::vector<int64_t> chunk_of_link(encounters.size());
  std::vector<int32_t> link_begin(static_cast<size_t>(num_chunks) + 1, 0);
  for (size_t e = 0; e < encounters.size(); ++e) {
    const EncounterLink& link = encounters[e];
    int64_t chunk = chunk_of(link.robot_b, link.trajectory_b, link.index_b);
    if (chunk < 0) chunk = chunk_of(link.robot_a, link.trajectory_a, link.index_a);
    chunk_of_link[e] = chunk;
    if (chunk >= 0) ++link_begin[static_cast<size_t>(chunk) + 1];
  }
  for (size_t c = 0; c < static_cast<size_t>(num_chunks); ++c) link_begin[c + 1] += link_begin[c];
  std::vector<int32_t> link_index(static_cast<size_t>(link_begin.back()));
  std::vector<int32_t> link_position(link_index.size());
  std::vector<int32_t> fill(link_begin.begin(), link_begin.end() - 1);
  int32_t placed = 0;
  for (size_t e = 0; e < encounters.size(); ++e) {
    if (chunk_of_link[e] < 0) continue;
    const auto slot = static_cast<size_t>(fill[static_cast<size_t>(chunk_of_link[e])]++);
    link_index[slot] = static_cast<int32_t>(e);
    link_position[slot] = placed++;
  }
  out.header.num_encounters = placed;
  ++work_.updates;
  work_.chunks += num_chunks;

  struct Chunk {
    ChunkId id;
    const Trajectory* trajectory = nullptr;
    int64_t first = 0;
    int64_t end = 0;
    size_t links = 0;      // [link_begin[links], link_begin[links + 1])
    Sent* sent = nullptr;  // nullptr: new
    bool send = false;
    bool read = false;
    bool candidate = true;  // may have moved past the tolerances (by node: see below)
    double moved = 0.0;
    std::vector<Pose2> poses;  // once read
  };
  std::vector<Chunk> chunks;
  chunks.reserve(static_cast<size_t>(num_chunks));
  for (size_t t = 0; t < trajectories.size(); ++t) {
    const Trajectory& trajectory = trajectories[t];
    for (int64_t first = 0; first < trajectory.num_poses; first += size) {
      Chunk c;
      c.id =
          ChunkId{trajectory.robot, trajectory.trajectory_id, static_cast<int32_t>(first / size)};
      c.trajectory = &trajectory;
      c.first = first;
      c.end = std::min(trajectory.num_poses, first + size);
      c.links = static_cast<size_t>(first_chunk[t] + first / size);
      const auto sent = sent_.find(c.id);
      c.sent = sent == sent_.end() ? nullptr : &sent->second;
      chunks.push_back(std::move(c));
    }
  }
  std::sort(chunks.begin(), chunks.end(),
            [](const Chunk& a, const Chunk& b) { return a.id < b.id; });
  // By node (Trajectory::node_of): only the chunks holding a keyframe whose node may have
  // moved it past the tolerances are candidates; the others' poses are not read.
  const bool by_node = options_.max_read_chunks == 0 && options_.tolerance_m > 0 &&
                       options_.tolerance_rad > 0 && !trajectories.empty() &&
                       std::all_of(trajectories.begin(), trajectories.end(),
                                   [](const Trajectory& t) { return t.node_of && t.node_pose; });
  std::vector<std::vector<Chunk*>> by_trajectory(trajectories.size());  // by chunk index
  std::vector<KeyframeMoves*> trajectory_moves(trajectories.size(), nullptr);
  std::vector<KeyframeMoves::Pass> passes(trajectories.size());
  if (!by_node) moves_.clear();
  // Whether the chunk's encounters are those it was last sent with.
  const auto same_links = [&](const Chunk& c) {
    const MergedMapChunk& sent = c.sent->chunk;
    const auto begin = static_cast<size_t>(link_begin[c.links]);
    const auto count = static_cast<size_t>(link_begin[c.links + 1]) - begin;
    if (sent.encounters.size() != count || sent.encounter_positions.size() != count) return false;
    for (size_t i = 0; i < count; ++i) {
      if (sent.encounter_positions[i] != link_position[begin + i] ||
          sent.encounters[i] != encounters[static_cast<size_t>(link_index[begin + i])]) {
        return false;
      }
    }
    return true;
  };
  const auto read = [&](Chunk* c) {
    c->read = true;
    c->poses.resize(static_cast<size_t>(c->end - c->first));
    c->trajectory->local_poses(c->first, c->end, c->poses.data());
  };
  const auto utimes_of = [](const Chunk& c) {
    std::vector<int64_t> utimes(static_cast<size_t>(c.end - c.first), 0);
    const std::vector<int64_t>& all = *c.trajectory->pose_utimes;
    for (int64_t i = c.first; i < c.end && i < static_cast<int64_t>(all.size()); ++i) {
      utimes[static_cast<size_t>(i - c.first)] = all[static_cast<size_t>(i)];
    }
    return utimes;
  };
  // Sent anyway: new, keyframes added or lost, encounters changed (or everything: `full`).
  std::vector<Chunk*> rest;
  for (Chunk& c : chunks) {
    c.send = full || c.sent == nullptr ||
             c.sent->chunk.local_poses.size() != static_cast<size_t>(c.end - c.first) ||
             !same_links(c);
    if (!c.send) rest.push_back(&c);
  }
  // The refresh: the least recently sent first, ties in the chunks' order.
  std::stable_sort(rest.begin(), rest.end(), [](const Chunk* a, const Chunk* b) {
    return a->sent->chunk.version < b->sent->chunk.version;
  });
  const auto refreshed =
      std::min(rest.size(), static_cast<size_t>(std::ceil(std::clamp(refresh, 0.0, 1.0) *
                                                          static_cast<double>(chunks.size()))));
  for (size_t i = 0; i < refreshed; ++i) rest[i]->send = true;
  rest.erase(rest.begin(), rest.begin() + static_cast<std::ptrdiff_t>(refreshed));
  // The poses of the least recently read: the chunks whose keyframes' times changed (a
  // restarted server's) go; those that moved compete for the budget, the farthest first.
  std::stable_sort(rest.begin(), rest.end(),
                   [](const Chunk* a, const Chunk* b) { return a->sent->read < b->sent->read; });
  if (options_.max_read_chunks > 0) {
    rest.resize(std::min(rest.size(), static_cast<size_t>(options_.max_read_chunks)));
  }
  if (by_node) {
    for (Chunk& c : chunks) {
      c.candidate = false;
      by_trajectory[static_cast<size_t>(c.trajectory - trajectories.data())].push_back(&c);
    }
    for (auto it = moves_.begin(); it != moves_.end();) {
      it = by_name.count({it->first.first, it->first.second}) != 0 ? std::next(it)
                                                                   : moves_.erase(it);
    }
    for (size_t t = 0; t < trajectories.size(); ++t) {
      const Trajectory& trajectory = trajectories[t];
      const std::vector<Chunk*>& of_t = by_trajectory[t];
      auto [it, fresh] = moves_.try_emplace({trajectory.robot, trajectory.trajectory_id}, options_);
      TrajectoryMoves& tm = it->second;
      if (trajectory.num_poses < tm.count) {  // a restarted trajectory
        tm.moves.Clear();
        tm.count = 0;
        fresh = true;
      }
      const auto sent_pose = [&](int64_t i) -> const Pose2* {
        const Chunk* c = of_t[static_cast<size_t>(i / size)];
        if (c->sent == nullptr) return nullptr;
        const std::vector<Pose2>& poses = c->sent->chunk.local_poses;
        return i - c->first < static_cast<int64_t>(poses.size())
                   ? &poses[static_cast<size_t>(i - c->first)]
                   : nullptr;
      };
      for (int64_t i = tm.count; i < trajectory.num_poses; ++i) {
        const Trajectory::NodeOffset node = trajectory.node_of(i);
        const double offset_m = node.T_node_key ? node.T_node_key->translation().norm() : 0.0;
        tm.moves.Add(static_cast<uint64_t>(i), static_cast<uint64_t>(i), node.node, node.T_node_key,
                     std::max(offset_m / options_.tolerance_m, 1.0 / options_.tolerance_rad),
                     sent_pose(i) != nullptr);
      }
      tm.count = trajectory.num_poses;
      trajectory_moves[t] = &tm.moves;
      if (std::all_of(of_t.begin(), of_t.end(), [](const Chunk* c) { return c->send; })) {
        // Every chunk goes anyway (a short trajectory's one growing chunk): no pose read
        // here; its nodes are examined when next asked.
        tm.moves.Skip();
        continue;
      }
      passes[t] = tm.moves.Examine(trajectory.node_pose,
                                   [&](uint64_t key, const Pose2& pose) -> std::optional<double> {
                                     const Pose2* sent = sent_pose(static_cast<int64_t>(key));
                                     if (sent == nullptr) return std::nullopt;
                                     return Measure(*sent, pose);
                                   });
      work_.nodes_examined += passes[t].nodes_examined;
      // A fresh trajectory's chunks are read (their keyframes' times are checked there).
      for (Chunk* c : of_t) c->candidate = c->candidate || fresh;
      for (const KeyframeMoves::Found& f : passes[t].moved) {
        of_t[static_cast<size_t>(f.key) / static_cast<size_t>(size)]->candidate = true;
      }
    }
  }
  std::vector<Chunk*> moved;
  for (Chunk* c : rest) {
    c->sent->read = update;
    if (!c->candidate) continue;  // none of its poses moved past the tolerances
    read(c);
    ++work_.read;
    if (c->sent->chunk.pose_utimes != utimes_of(*c)) {
      c->send = true;
    } else if ((c->moved = Moved(c->sent->chunk.local_poses, c->poses)) > 0.0) {
      moved.push_back(c);
    }
  }
  std::stable_sort(moved.begin(), moved.end(),
                   [](const Chunk* a, const Chunk* b) { return a->moved > b->moved; });
  if (options_.max_moved_chunks > 0) {
    moved.resize(std::min(moved.size(), static_cast<size_t>(options_.max_moved_chunks)));
  }
  for (Chunk* c : moved) c->send = true;
  work_.moved += static_cast<int64_t>(moved.size());
  // By node: the poses sent now are where their keyframes are placed; moved ones not sent
  // (within the tolerances after all, or past the budget) keep their measure.
  for (size_t t = 0; by_node && t < trajectories.size(); ++t) {
    std::vector<KeyframeMoves::Found> deferred;
    for (const KeyframeMoves::Found& f : passes[t].moved) {
      if (!by_trajectory[t][static_cast<size_t>(f.key) / static_cast<size_t>(size)]->send) {
        deferred.push_back(f);
      }
    }
    trajectory_moves[t]->Settle(deferred);
    for (const Chunk* c : by_trajectory[t]) {
      if (!c->send) continue;
      for (int64_t i = c->first; i < c->end; ++i) {
        trajectory_moves[t]->PlacedNow(static_cast<int32_t>(i));
      }
    }
  }
  // The chunks to send, at their current content and this update's version.
  for (Chunk& c : chunks) {
    if (!c.send) continue;
    if (!c.read) read(&c);
    MergedMapChunk chunk;
    chunk.utime = utime;
    chunk.version = update;
    chunk.robot = std::get<0>(c.id);
    chunk.trajectory_id = std::get<1>(c.id);
    chunk.chunk_index = std::get<2>(c.id);
    chunk.pose_utimes = utimes_of(c);
    chunk.local_poses = std::move(c.poses);
    for (int32_t slot = link_begin[c.links]; slot < link_begin[c.links + 1]; ++slot) {
      chunk.encounters.push_back(
          encounters[static_cast<size_t>(link_index[static_cast<size_t>(slot)])]);
      chunk.encounter_positions.push_back(link_position[static_cast<size_t>(slot)]);
    }
    out.chunks.push_back(chunk);
    ++work_.sent;
    sent_[c.id] = Sent{std::move(chunk), update};
  }
  // Chunks that no longer exist (a trajectory lost keyframes: a server restart) are forgotten.
  auto current = chunks.begin();
  for (auto it = sent_.begin(); it != sent_.end();) {
    while (current != chunks.end() && current->id < it->first) ++current;
    it = current != chunks.end() && current->id == it->first ? std::next(it) : sent_.erase(it);
  }
  for (const Trajectory& t : trajectories) {
    MergedMapHeader::Trajectory h;
    h.robot = t.robot;
    h.trajectory_id = t.trajectory_id;
    h.anchored = t.anchored;
    h.T_global_local = t.T_global_local;
    h.num_poses = static_cast<int32_t>(t.num_poses);
    for (int32_t k = 0; static_cast<int64_t>(k) * size < h.num_poses; ++k) {
      h.chunk_versions.push_back(sent_.at(ChunkId{t.robot, t.trajectory_id, k}).chunk.version);
    }
    out.header.trajectories.push_back(std::move(h));
  }
  return out;
}

}  // namespace anchormap
