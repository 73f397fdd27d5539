#include "tools/render/server_output.h"

#include <cmath>
#include <map>
#include <utility>

// GCC 12 warns inside lcm_coretypes.h when it inlines the int8 array decode of
// grid_tile_t (bounds it cannot prove: -Wstringop-overflow, -Wrestrict); the generated
// decode checks every size against the buffer. (Clang has neither warning.)
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wstringop-overflow"
#pragma GCC diagnostic ignored "-Wrestrict"
#endif
#include "anchormap/anchor_covariances_t.hpp"
#include "anchormap/grid_tile_t.hpp"
#include "anchormap/server_status_t.hpp"
#include "common/bus/lcm_log.h"
#include "common/bus/merged_map_assembler.h"

namespace anchormap::render {
namespace {

// The assembled map as render's view; nullopt when a pose or anchor is not finite.
std::optional<MergedMap> FromAssembled(const anchormap::MergedMap& assembled) {
  MergedMap map;
  map.utime = assembled.utime;
  map.update = assembled.update;
  for (const MergedTrajectory& t : assembled.trajectories) {
    if (t.pose_utimes.size() != t.poses.size() || !t.T_global_local.IsFinite()) {
      return std::nullopt;
    }
    TrajectoryView view;
    view.key = {t.robot, t.trajectory_id};
    view.anchored = t.anchored;
    view.T_global_local = t.T_global_local;
    view.utimes = t.pose_utimes;
    for (const Pose2& pose : t.poses) {
      if (!pose.IsFinite()) return std::nullopt;
      view.poses.push_back(pose);
    }
    map.trajectories.push_back(std::move(view));
  }
  for (const anchormap::EncounterLink& link : assembled.encounters) {
    map.encounters.push_back({{link.robot_a, link.trajectory_a},
                              link.index_a,
                              {link.robot_b, link.trajectory_b},
                              link.index_b,
                              link.kind});
  }
  return map;
}

std::optional<GridTile> FromMessage(const anchormap::grid_tile_t& message) {
  if (message.width <= 0 || message.height <= 0 || message.width > 100000 ||
      message.height > 100000 || !(message.resolution > 0.0) ||
      static_cast<int>(message.cells.size()) != message.height) {
    return std::nullopt;
  }
  GridTile tile;
  tile.update = message.update;
  tile.resolution_m = message.resolution;
  tile.tile_x = message.tile_x;
  tile.tile_y = message.tile_y;
  tile.width = message.width;
  tile.height = message.height;
  tile.cells.reserve(static_cast<size_t>(message.width) * message.height);
  for (const auto& row : message.cells) {
    if (static_cast<int>(row.size()) != message.width) return std::nullopt;
    tile.cells.insert(tile.cells.end(), row.begin(), row.end());
  }
  return tile;
}

// DecodeAs that also turns exceptions into "does not decode": lcm-gen's decoders resize
// vectors to the counts in the message, so a corrupt negative count throws.
template <typename T>
std::optional<T> SafeDecode(const LogEvent& event) {
  try {
    return DecodeAs<T>(event);
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

}  // namespace

const Pose2* MergedMap::FindPose(const TrajectoryKey& trajectory, int index) const {
  for (const TrajectoryView& t : trajectories) {
    if (!(t.key == trajectory)) continue;
    if (index < 0 || index >= static_cast<int>(t.poses.size())) return nullptr;
    return &t.poses[index];
  }
  return nullptr;
}

size_t MergedMap::NumPoses() const {
  size_t n = 0;
  for (const TrajectoryView& t : trajectories) n += t.poses.size();
  return n;
}

Status ReadServerOutput(const std::string& path, const ChannelNames& channels, ServerOutput* output,
                        Authenticator* authenticator) {
  LcmLogReader reader;
  if (Status status = reader.Open(path); !status.ok()) return status;
  ServerOutput result;
  // A grid update is a run of tiles with the same update number. The grid is the newest
  // version of every tile: the server sends only the tiles that changed (a tile its map
  // left, as unknown), and every tile at a slow period.
  struct KeptTile {
    GridTile tile;
    int64_t run = 0;
  };
  std::map<std::pair<int, int>, KeptTile> newest_tiles;
  int64_t run = -1;
  int64_t run_update = 0;
  MergedMapAssembler assembler({channels.map_header, channels.map_chunks, channels.merged_map});
  while (std::optional<LogEvent> event = reader.Next()) {
    const std::string& channel = event->channel;
    const bool ours = assembler.IsMapChannel(channel) || channel == channels.grid_tiles ||
                      channel == channels.server_status || channel == channels.anchor_covariances;
    if (!ours) continue;
    if (!OpenLoggedEvent(authenticator, &*event).ok()) {
      ++result.unauthenticated;
      continue;
    }
    if (assembler.IsMapChannel(event->channel)) {
      bool completed = false;
      if (!assembler.Accept(event->channel, event->data.data(), event->data.size(), &completed)
               .ok()) {
        ++result.undecodable;
        continue;
      }
      if (!completed) continue;
      std::optional<MergedMap> map = FromAssembled(*assembler.map());
      if (!map) {
        ++result.undecodable;
        continue;
      }
      ++result.merged_maps;
      result.map = std::move(map);
    } else if (event->channel == channels.grid_tiles) {
      const auto message = SafeDecode<anchormap::grid_tile_t>(*event);
      std::optional<GridTile> tile = message ? FromMessage(*message) : std::nullopt;
      if (!tile) {
        ++result.undecodable;
        continue;
      }
      ++result.grid_tile_messages;
      if (run < 0 || tile->update != run_update) {
        ++run;
        run_update = tile->update;
      }
      const std::pair<int, int> key(tile->tile_x, tile->tile_y);
      newest_tiles[key] = KeptTile{std::move(*tile), run};
    } else if (event->channel == channels.server_status) {
      const auto message = SafeDecode<anchormap::server_status_t>(*event);
      if (!message || message->num_reasons != static_cast<int>(message->rejection_reasons.size()) ||
          message->rejection_counts.size() != message->rejection_reasons.size()) {
        ++result.undecodable;
        continue;
      }
      ServerStatus status{message->update,
                          message->num_robots,
                          message->num_trajectories,
                          message->num_anchored,
                          message->keyframes,
                          message->encounters,
                          {}};
      for (int i = 0; i < message->num_reasons; ++i) {
        status.rejections.emplace_back(message->rejection_reasons[i], message->rejection_counts[i]);
      }
      result.status = std::move(status);
    } else if (event->channel == channels.anchor_covariances) {
      const auto message = SafeDecode<anchormap::anchor_covariances_t>(*event);
      if (!message || message->num_anchors != static_cast<int>(message->anchors.size())) {
        ++result.undecodable;
        continue;
      }
      ++result.covariance_messages;
      for (const anchormap::anchor_covariance_t& anchor : message->anchors) {
        const double variance = anchor.covariance[0] + anchor.covariance[4];
        if (!std::isfinite(variance) || variance < 0.0) {
          ++result.undecodable;
          continue;
        }
        result.anchor_samples.push_back({message->update,
                                         message->utime,
                                         {anchor.robot, anchor.trajectory_id},
                                         std::sqrt(variance)});
      }
    }
  }
  result.grid_update = run_update;
  for (auto& [key, kept] : newest_tiles) {
    if (kept.run != run) ++result.grid_tiles_from_earlier_updates;
    result.grid.push_back(std::move(kept.tile));
  }
  if (result.map) {
    for (const EncounterLink& link : result.map->encounters) {
      if (!result.map->FindPose(link.a, link.index_a) ||
          !result.map->FindPose(link.b, link.index_b)) {
        ++result.dangling_links;
      }
    }
  }
  *output = std::move(result);
  return Status::Ok();
}

}  // namespace anchormap::render

#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif
