#include "common/bus/merged_map_assembler.h"

#include <algorithm>
#include <utility>
#include <vector>

#include "common/bus/map_codec.h"

namespace anchormap {

Status MergedMapAssembler::Accept(const std::string& channel, const void* data, size_t size,
                                  bool* completed) {
  if (completed != nullptr) *completed = false;
  bool complete = false;
  if (channel == channels_.merged_map) {
    Result<MergedMap> map = DecodeMergedMap(data, size);
    if (!map.ok()) return map.status();
    map_ = std::move(*map);
    header_.reset();
    missing_ = 0;
    complete = true;
  } else if (channel == channels_.header) {
    Result<MergedMapHeader> header = DecodeMergedMapHeader(data, size);
    if (!header.ok()) return header.status();
    // A server that restarted counts its updates from 0 again: its chunks' versions could
    // collide with the old ones.
    if (header_ && header->update < header_->update) held_.clear();
    header_ = std::move(*header);
    ++headers_;
    complete = TryComplete();
  } else if (channel == channels_.chunks) {
    Result<MergedMapChunk> chunk = DecodeMergedMapChunk(data, size);
    if (!chunk.ok()) return chunk.status();
    ++chunks_;
    ChunkId id{chunk->robot, chunk->trajectory_id, chunk->chunk_index};
    held_[std::move(id)] = std::move(*chunk);
    // A chunk that arrives after its header (the bus reordered them) completes the map.
    if (header_ && missing_ > 0) complete = TryComplete();
  } else {
    return Status::Error(ErrorCode::kInvalidValue, "not a merged map channel: " + channel);
  }
  if (complete) ++complete_maps_;
  if (completed != nullptr) *completed = complete;
  return Status::Ok();
}

bool MergedMapAssembler::TryComplete() {
  const MergedMapHeader& header = *header_;
  missing_ = 0;
  for (const MergedMapHeader::Trajectory& t : header.trajectories) {
    for (size_t k = 0; k < t.chunk_versions.size(); ++k) {
      const auto it = held_.find(ChunkId{t.robot, t.trajectory_id, static_cast<int32_t>(k)});
      if (it == held_.end() || it->second.version != t.chunk_versions[k]) ++missing_;
    }
  }
  if (missing_ > 0) return false;
  MergedMap map;
  map.utime = header.utime;
  map.update = header.update;
  std::vector<std::pair<int32_t, EncounterLink>> encounters;
  for (const MergedMapHeader::Trajectory& t : header.trajectories) {
    MergedTrajectory out;
    out.robot = t.robot;
    out.trajectory_id = t.trajectory_id;
    out.anchored = t.anchored;
    out.T_global_local = t.T_global_local;
    for (size_t k = 0; k < t.chunk_versions.size(); ++k) {
      const MergedMapChunk& chunk =
          held_.at(ChunkId{t.robot, t.trajectory_id, static_cast<int32_t>(k)});
      for (size_t i = 0; i < chunk.local_poses.size(); ++i) {
        out.poses.push_back(Compose(t.T_global_local, chunk.local_poses[i]));
        out.pose_utimes.push_back(i < chunk.pose_utimes.size() ? chunk.pose_utimes[i] : 0);
      }
      for (size_t e = 0; e < chunk.encounters.size(); ++e) {
        encounters.emplace_back(chunk.encounter_positions[e], chunk.encounters[e]);
      }
    }
    // Chunks whose sizes do not add up to the header's count: not this header's chunks.
    if (static_cast<int64_t>(out.poses.size()) != t.num_poses) {
      ++missing_;
      return false;
    }
    map.trajectories.push_back(std::move(out));
  }
  if (static_cast<int64_t>(encounters.size()) != header.num_encounters) {
    ++missing_;
    return false;
  }
  std::stable_sort(encounters.begin(), encounters.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  for (auto& [position, link] : encounters) map.encounters.push_back(std::move(link));
  map_ = std::move(map);
  return true;
}

}  // namespace anchormap
