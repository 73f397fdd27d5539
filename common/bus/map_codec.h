#pragma once
// Wire bytes <-> the mapping server's output values (merged map header and chunks, the
// merged map as one message of servers before them, anchor covariances, grid tiles, status), with
// the same pre-flight size checks as codec.h. The server encodes; tests and tools (render, eval)
// decode.

#include <cstddef>
#include <cstdint>
#include <vector>

#include "common/bus/codec.h"
#include "common/types/map_outputs.h"

namespace anchormap {

std::vector<uint8_t> EncodeMergedMap(const MergedMap& map);
Result<MergedMap> DecodeMergedMap(const void* data, size_t size);
std::vector<uint8_t> EncodeMergedMapHeader(const MergedMapHeader& header);
Result<MergedMapHeader> DecodeMergedMapHeader(const void* data, size_t size);
std::vector<uint8_t> EncodeMergedMapChunk(const MergedMapChunk& chunk);
Result<MergedMapChunk> DecodeMergedMapChunk(const void* data, size_t size);
std::vector<uint8_t> EncodeAnchorCovariances(const AnchorCovariances& anchors);
Result<AnchorCovariances> DecodeAnchorCovariances(const void* data, size_t size);
std::vector<uint8_t> EncodeGridTile(const GridTile& tile);
Result<GridTile> DecodeGridTile(const void* data, size_t size);
std::vector<uint8_t> EncodeServerStatus(const ServerStatus& status);
Result<ServerStatus> DecodeServerStatus(const void* data, size_t size);

}  // namespace anchormap
