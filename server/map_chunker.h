#pragma once
// Splits the merged map into a header and chunks of bounded size for the bus
// (MergedMapHeader, MergedMapChunk in common/types/map_outputs.h): chunk k of a trajectory
// holds its keyframes [k * chunk_poses, (k + 1) * chunk_poses) with their poses in the
// trajectory's local frame, and the encounters whose second keyframe (else the first) lies
// there. It remembers what it sent, so that a map update sends only the chunks whose content
// changed: poses added, a local pose moved past the tolerance, encounters changed. Anchors
// travel in the header, so a merge that moves whole trajectories sends no chunk. A chunk's
// version is the update it was last sent at; the header names every chunk's version.
//
// Its cost can be bounded by its options, not by the map: a correction moves the whole map
// (late in a 20-robot run 83 % of the chunks moved past the tolerance at every update), so
// an update may read the poses of a bounded number of chunks only, the least recently read
// first, and of those that moved send a bounded number, the farthest moved first; the
// others keep their version (a subscriber's map holds them as last sent) and are read
// again at a later update. Chunks whose keyframes or encounters changed always go
// (the team's new keyframes: their number follows the team, not the map). A share of the
// chunks, the least recently sent first, goes out again at every update whatever changed
// (the caller's `refresh`): every chunk within a bounded number of updates, spread over
// them instead of all at once.

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

#include "common/types/map_outputs.h"
#include "server/keyframe_moves.h"

namespace anchormap {

struct MapChunkerOptions {
  int32_t chunk_poses = 256;  // 256 poses: 8 kB of poses, within one 64 kB LCM datagram
  // A chunk is sent again when one of its local poses moved more than this since it was
  // sent (the viewer's rounding: 1 mm, 1e-4 rad).
  double tolerance_m = 0.001;
  double tolerance_rad = 1e-4;
  // At most this many chunks per update sent only because a pose moved past the
  // tolerance, the farthest moved (in tolerances) first (0: no limit).
  int32_t max_moved_chunks = 0;
  // At most this many chunks per update whose poses are read to see whether they moved,
  // the least recently read first, besides the chunks sent anyway (0: every chunk).
  // Both bounds are off by default: with them (32 read, 16 moved) 20 robots' maps were
  // flat at ~35-40 chunks per map instead of growing to ~85 at 900 s, but a subscriber's
  // map lagged the server's by a median 14 cm late in the run (max 26 cm), for a saving
  // within the noise (docs/ARCHITECTURE.md, "flat21").
  int32_t max_read_chunks = 0;
};

class MapChunker {
 public:
  explicit MapChunker(const MapChunkerOptions& options = {}) : options_(options) {}

  // One trajectory of the map as the bus carries it.
  struct Trajectory {
    std::string robot;
    int64_t trajectory_id = 0;
    bool anchored = false;
    Pose2 T_global_local;
    int64_t num_poses = 0;
    // The keyframes' times; 0 for those beyond its end.
    const std::vector<int64_t>* pose_utimes = nullptr;
    // Writes the poses [first, end) in the trajectory's local frame to out[0, end - first).
    std::function<void(int64_t first, int64_t end, Pose2* out)> local_poses;
    // Optional, both or neither: keyframe i's local pose is node_of(i).node's (node_pose, in
    // the same frame) (+) node_of(i).T_node_key (the reduced pose graph's aliases; nullopt:
    // the keyframe is its own node). With them (and no max_read_chunks), an update reads
    // only the chunks that hold a keyframe whose node may have moved it past the tolerance
    // (KeyframeMoves), not every chunk: the same chunks go out. A keyframe's node and
    // offset, and its time, never change.
    struct NodeOffset {
      uint64_t node = 0;
      std::optional<Pose2> T_node_key;
    };
    std::function<NodeOffset(int64_t index)> node_of;
    std::function<Pose2(uint64_t node)> node_pose;
  };
  struct Split {
    std::vector<MergedMapChunk> chunks;  // to send before the header
    MergedMapHeader header;
  };
  // The header of the map and the chunks to send, in the order robot, trajectory, index:
  // every chunk when `full`; otherwise those new or whose keyframes or encounters changed
  // since last sent, those read (max_read_chunks) whose poses moved past the tolerance
  // within max_moved_chunks (the farthest first), and ceil(refresh x the chunks) more, the
  // least recently sent first (refresh in [0, 1]; ties in the chunks' order). Each at its
  // current content.
  Split Update(int64_t utime, int64_t update, const std::vector<Trajectory>& trajectories,
               const std::vector<EncounterLink>& encounters, bool full, double refresh = 0.0);
  // The same for a map with global poses (each made local by its trajectory's anchor).
  Split Update(const MergedMap& map, bool full, double refresh = 0.0);

  // What the updates cost, counted for the status.
  struct Work {
    int64_t updates = 0;
    int64_t chunks = 0;          // in the maps split
    int64_t read = 0;            // chunks whose poses were read to compare
    int64_t moved = 0;           // of those, moved past the tolerances
    int64_t sent = 0;            // chunks sent (new, changed, moved, refreshed)
    int64_t nodes_examined = 0;  // by node: the nodes' poses read
  };
  const Work& work() const { return work_; }

 private:
  using ChunkId = std::tuple<std::string, int64_t, int32_t>;  // robot, trajectory, index
  struct Sent {
    MergedMapChunk chunk;  // as last sent
    int64_t read = 0;      // the update its poses were last read at
  };
  // How far `now` moved from `sent`, in tolerances: the largest of |dx|, |dy| over
  // tolerance_m and |dtheta| over tolerance_rad; 0 when none passed its tolerance (+inf for
  // a move past a tolerance of 0).
  double Moved(const std::vector<Pose2>& sent, const std::vector<Pose2>& now) const;

  // Per trajectory with node_of: its keyframes by node (measured in tolerances: a chunk
  // moved when a pose's measure passes 1) and how many it holds.
  struct TrajectoryMoves {
    explicit TrajectoryMoves(const MapChunkerOptions& options)
        : moves(kCandidateMeasure, 1.0 / options.tolerance_m) {}
    KeyframeMoves moves;
    int64_t count = 0;
  };
  // Below 1 by far more than round-off: a pose below it is surely within the tolerances.
  static constexpr double kCandidateMeasure = 1.0 - 1e-6;
  // Max over the components of |difference| / tolerance (Moved's measure before its cut).
  double Measure(const Pose2& sent, const Pose2& now) const;

  MapChunkerOptions options_;
  std::map<ChunkId, Sent> sent_;
  std::map<std::pair<std::string, int64_t>, TrajectoryMoves> moves_;
  Work work_;
};

}  // namespace anchormap
