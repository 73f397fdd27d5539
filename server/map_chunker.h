#pragma once
// Splits the merged map into a header and chunks of bounded size for the bus
// (MergedMapHeader, MergedMapChunk in common/types/map_outputs.h): chunk k of a trajectory
// holds its keyframes [k * chunk_poses, (k + 1) * chunk_poses) with their poses in the
// trajectory's local frame, and the encounters whose second keyframe (else the first) lies
// there. It remembers what it sent, so that a map update sends only the chunks whose content
// changed: poses added, a local pose moved past the tolerance, encounters changed. Anchors
// travel in the header, so a merge that moves whole trajectories sends no chunk. A chunk's
// version is the update it was last sent at; the header names every chunk's version.

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
};

class MapChunker {
 public:
  explicit MapChunker(const MapChunkerOptions& options = {}) : options_(options) {}

  struct Split {
    std::vector<MergedMapChunk> chunks;  // to send before the header
    MergedMapHeader header;
  };
  // The chunks of `map` that changed since the last call (every chunk when `full`, at its
  // current content), and the header.
  Split Update(const MergedMap& map, bool full);

 private:
  using ChunkId = std::tuple<std::string, int64_t, int32_t>;  // robot, trajectory, index
  bool Changed(const MergedMapChunk& sent, const MergedMapChunk& now) const;

  MapChunkerOptions options_;
  std::map<ChunkId, MergedMapChunk> sent_;
};

}  // namespace anchormap
