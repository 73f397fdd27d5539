#pragma once
// Puts the merged map back together from the bus: the server's header and chunks
// (anchormap.merged_map_header_t, merged_map_chunk_t; server/map_chunker.h splits), or the
// single merged_map_t of servers (and logs) from before the chunks. The map is complete
// when every chunk the newest header names is held at the version it names; the assembler
// then builds it (global poses = the header's anchor times the chunk's local poses,
// encounters in the server's order) and keeps it until the next complete one. One lost
// chunk leaves the previous complete map in place until the server sends the chunk again.
// Bytes in, values out: no LCM here beyond the codec. One assembler for every reader (the
// viewer, anchormap-render, anchormap-eval, the tests' checkers).

#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <tuple>
#include <utility>

#include "common/bus/channels.h"
#include "common/types/map_outputs.h"
#include "common/util/status.h"

namespace anchormap {

struct MergedMapChannels {
  std::string header = channels::kMapHeader;
  std::string chunks = channels::kMapChunks;
  std::string merged_map = channels::kMergedMap;  // one message per map (before the chunks)
};

class MergedMapAssembler {
 public:
  explicit MergedMapAssembler(MergedMapChannels channels = {}) : channels_(std::move(channels)) {}

  bool IsMapChannel(const std::string& channel) const {
    return channel == channels_.header || channel == channels_.chunks ||
           channel == channels_.merged_map;
  }
  // Takes one message of a map channel. The error of a message that does not decode
  // (nothing changes then); ok otherwise, with *completed (when given) set when the message
  // made a new complete map.
  Status Accept(const std::string& channel, const void* data, size_t size,
                bool* completed = nullptr);
  // The newest complete map.
  const std::optional<MergedMap>& map() const { return map_; }
  // Chunks the newest header names that are missing or at another version.
  int64_t missing_chunks() const { return missing_; }
  int64_t headers() const { return headers_; }
  int64_t chunks() const { return chunks_; }
  int64_t complete_maps() const { return complete_maps_; }

 private:
  using ChunkId = std::tuple<std::string, int64_t, int32_t>;  // robot, trajectory, index
  // Counts the missing chunks of the header; builds the map when none is.
  bool TryComplete();

  MergedMapChannels channels_;
  std::optional<MergedMapHeader> header_;
  std::map<ChunkId, MergedMapChunk> held_;
  std::optional<MergedMap> map_;
  int64_t missing_ = 0;
  int64_t headers_ = 0;
  int64_t chunks_ = 0;
  int64_t complete_maps_ = 0;
};

}  // namespace anchormap
