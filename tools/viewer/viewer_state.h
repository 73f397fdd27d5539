#pragma once
// What the web page shows, as JSON, and what changed since the last push. Bus-free: it
// takes decoded, validated values (common/types/map_outputs.h) and knows nothing of LCM
// or of the web server.
//
// Two messages (docs/DAEMONS.md, "anchormap-viewer" has the fields):
//   Full()      {"type": "full", ...}: everything, for a browser that connects;
//   TakeDelta() {"type": "delta", ...}: only what changed since the previous TakeDelta():
//               trajectories whose poses moved from the first moved keyframe on
//               ("from", "poses" from there, "num_poses"), removed trajectories, the
//               encounter list from its first change, changed grid tiles and dropped
//               ones ("removed_tiles": "x,y"), and the anchor covariances and status when
//               they changed.
// The page applies both the same way, so Full() at delta k, then TakeDelta() k+1, gives
// Full() at k+1 (the unit test checks exactly that). Poses are rounded (1 mm, 1e-4 rad)
// before they are compared and sent, so a pose that moved by less does not travel.
// A server restart (a map, status or tile whose update number went back) clears the
// state; the page sees "restarts" grow.

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/types/map_outputs.h"
#include "common/util/reject_counter.h"

namespace anchormap::viewer {

struct ViewerStateOptions {
  double position_quantum_m = 0.001;
  double angle_quantum_rad = 1e-4;
  int32_t max_tiles = 20000;           // tiles held; more are refused (bounded memory)
  int32_t max_tile_side_cells = 1024;  // a tile wider or taller than this is refused
  // A grid update is a run of tiles with one update number; a tile that none of the last
  // this many runs refreshed is dropped (0 = never). The server sends only the tiles that
  // changed (a tile its map left, as unknown), so a tile it did not send is still current.
  int32_t max_grid_runs_back = 0;
};

class ViewerState {
 public:
  explicit ViewerState(ViewerStateOptions options = {});

  // Each returns false (and counts why in rejections()) when it refuses the value.
  // `wall_utime` is when it arrived (the page shows the last one).
  bool ApplyMergedMap(const MergedMap& map, int64_t wall_utime);
  bool ApplyGridTile(const GridTile& tile, int64_t wall_utime);
  bool ApplyAnchorCovariances(const AnchorCovariances& anchors, int64_t wall_utime);
  bool ApplyStatus(const ServerStatus& status, int64_t wall_utime);

  bool HasChanges() const;
  // The changes since the previous call as a delta message (numbered seq() + 1).
  nlohmann::json TakeDelta();
  // Everything, numbered seq(): the last delta's number. Meant to be called right after
  // TakeDelta() (the viewer does), so that the next delta follows it.
  nlohmann::json Full() const;

  int64_t seq() const { return seq_; }
  int64_t restarts() const { return restarts_; }
  int64_t map_update() const { return map_update_; }
  size_t num_trajectories() const { return trajectories_.size(); }
  size_t num_tiles() const { return tiles_.size(); }
  int64_t num_keyframes() const;
  const RejectCounter& rejections() const { return rejections_; }

 private:
  struct Trajectory {
    std::string robot;
    int64_t id = 0;
    bool anchored = false;
    std::vector<double> anchor;  // x, y, theta (rounded)
    std::vector<double> poses;   // x0, y0, theta0, x1, ... (rounded)
    size_t first_changed = 0;    // pose index; kUnchanged when nothing changed
  };
  struct Tile {
    int32_t x = 0, y = 0, width = 0, height = 0;
    double resolution_m = 0;
    int64_t update = 0;
    std::vector<int8_t> cells;
    bool changed = false;
    int64_t run = 0;  // the grid run that last brought it
  };
  static constexpr size_t kUnchanged = static_cast<size_t>(-1);

  enum Stream { kMap = 0, kTiles, kCovariances, kStatus, kNumStreams };
  // Detects a restart: a stream's update number going back (each stream on its own, since
  // the server stamps them at different times).
  void NoteUpdate(Stream stream, int64_t update);
  void Clear();
  double RoundPosition(double v) const;
  double RoundAngle(double v) const;
  nlohmann::json TrajectoryJson(const std::string& key, const Trajectory& t, size_t from) const;
  static nlohmann::json TileJson(const Tile& tile);
  nlohmann::json StatusJson() const;

  ViewerStateOptions options_;
  int64_t seq_ = 0;
  int64_t restarts_ = 0;
  // The server's instance id (0: none seen, or an offline run); a new one is a restart.
  int64_t instance_id_ = 0;
  // A restart was inferred from an update number going back since the last status: the
  // new instance's id, when it comes, is the same restart.
  bool restart_inferred_ = false;
  int64_t last_update_[kNumStreams] = {-1, -1, -1, -1};  // per stream, since the last restart
  int64_t map_update_ = -1;
  int64_t map_utime_ = 0;
  int64_t last_message_wall_utime_ = 0;
  std::map<std::string, Trajectory> trajectories_;  // key "ROBOT/ID"
  std::vector<std::string> removed_;                // since the last delta
  std::vector<nlohmann::json> encounters_;          // [ta, ia, tb, ib, kind]
  size_t encounters_first_changed_ = kUnchanged;
  std::map<std::pair<int32_t, int32_t>, Tile> tiles_;
  bool tiles_cleared_ = false;
  std::vector<std::string> removed_tiles_;  // "x,y", since the last delta
  int64_t grid_run_ = 0;
  int64_t grid_run_update_ = -1;
  nlohmann::json covariances_;  // null until the first
  bool covariances_changed_ = false;
  nlohmann::json status_;  // null until the first
  bool status_changed_ = false;
  bool meta_changed_ = false;  // map update/utime, restarts, wall time
  RejectCounter rejections_;
};

// "ROBOT/ID", the trajectories' key in the JSON messages.
std::string TrajectoryKey(const std::string& robot, int64_t id);
// An encounter link's kind as the page names it: the wire's ("direct", "scan", "loop";
// common/types/constraint_kind.h).
std::string EncounterKind(const EncounterLink& link);

}  // namespace anchormap::viewer
