#pragma once
// The bytes of one journaled match result (MatchPool's RecordedMatch): the server's journal
// stores them as events of their own channel (server/node), so that a restart reuses the
// results instead of running the matches again. Little-endian plain values; every double
// bit for bit, so a reused result is the computed one exactly. Refused (kDecodeFailed, with
// the reason) when the magic, the version or the size is wrong.

#include <cstddef>
#include <cstdint>
#include <vector>

#include "common/util/status.h"
#include "server/match_pool.h"

namespace anchormap {

std::vector<uint8_t> EncodeRecordedMatch(const RecordedMatch& match);
Result<RecordedMatch> DecodeRecordedMatch(const uint8_t* data, size_t size);

}  // namespace anchormap
