#pragma once
// Snapshot files beside the journal (issue 13: periodic snapshots keep restarts fast):
// DIR/snapshot-<journal events covered, 12 digits>.bin, each written whole or not at all
// (DIR/snapshot.tmp, fsync, rename over the final name, fsync DIR), so a crash at any point
// leaves the previous snapshots intact. The newest `keep` are kept: if the newest turns out
// unreadable, the one before it (then the whole journal) is used. The journal itself is
// never cut: it stays the ground truth, readable by lcm-logplayer. What a snapshot holds is
// server/snapshot_codec.h's business; this file only stores bytes.

#include <cstdint>
#include <string>
#include <vector>

#include "common/util/status.h"

namespace anchormap {

// Writes `bytes` as the snapshot covering `journal_events` events, then removes all but the
// newest `keep` snapshot files (keep >= 1).
Status WriteSnapshotFile(const std::string& dir, int64_t journal_events,
                         const std::vector<uint8_t>& bytes, int keep);

// The snapshot files in `dir`, newest (most journal events) first.
std::vector<std::string> ListSnapshotFiles(const std::string& dir);

Result<std::vector<uint8_t>> ReadSnapshotFile(const std::string& path);

}  // namespace anchormap
