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
// The cost of an update follows what it sends, and a correction moves the whole map (late
// in a 20-robot run 83 % of the chunks moved past the tolerance at every update), so the
// chunks that only moved go out by a budget, the farthest moved first; the rest keep their
// version (a subscriber's map holds them as last sent) and go at a later update. Chunks
// whose keyframes or encounters changed always go (the team's new keyframes: their number
// follows the team, not the map). A share of the chunks, the least recently sent first,
// goes out again at every update whatever changed (the caller's `refresh`): every chunk
// within a bounded number of updates, spread over them instead of all at once.

#include <cstdint>
#include <map>
#include <string>
#include <tuple>
#include <vector>

#include "common/types/map_outputs.h"

namespace anchormap {

struct MapChunkerOptions {
  int32_t chunk_poses = 256;  // 256 poses: 8 kB of poses, within one 64 kB LCM datagram
  // A chunk is sent again when one of its local poses moved more than this since it was
  // sent (the viewer's rounding: 1 mm, 1e-4 rad).
  double tolerance_m = 0.001;
  double tolerance_rad = 1e-4;
  // At most this many chunks per update sent only because a pose moved past the
  // tolerance, the farthest moved (in tolerances) first (0: no limit). 16 chunks are 4096
  // poses, ~130 kB.
  int32_t max_moved_chunks = 16;
};

class MapChunker {
 public:
  explicit MapChunker(const MapChunkerOptions& options = {}) : options_(options) {}

  struct Split {
    std::vector<MergedMapChunk> chunks;  // to send before the header
    MergedMapHeader header;
  };
  // The header of `map` and the chunks to send: every chunk when `full`; otherwise those
  // new or whose keyframes or encounters changed since last sent, those whose poses moved
  // past the tolerance within max_moved_chunks (the farthest first), and ceil(refresh x
  // the chunks) more, the least recently sent first (refresh in [0, 1]; ties in the order
  // robot, trajectory, index). Each at its current content.
  Split Update(const MergedMap& map, bool full, double refresh = 0.0);

 private:
  using ChunkId = std::tuple<std::string, int64_t, int32_t>;  // robot, trajectory, index
  // Keyframes or encounters differ: the chunk must go.
  static bool Rewritten(const MergedMapChunk& sent, const MergedMapChunk& now);
  // How far the chunk's poses moved since sent, in tolerances: the largest of |dx|, |dy|
  // over tolerance_m and |dtheta| over tolerance_rad; 0 when none passed its tolerance
  // (+inf for a move past a tolerance of 0).
  double Moved(const MergedMapChunk& sent, const MergedMapChunk& now) const;

  MapChunkerOptions options_;
  std::map<ChunkId, MergedMapChunk> sent_;
};

}  // namespace anchormap
