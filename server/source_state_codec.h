#pragma once
// The scan-matching sources' state (loop_closure_state.h, scan_encounter_state.h) and the
// reduced graph's folder state (keyframe_fold_state.h) in a snapshot: every double bit for bit, in
// the server's byte codec (server/byte_codec.h); a match result as its journal record
// (server/recorded_match_codec.h) holds it.

#include <cstdint>

#include "server/byte_codec.h"
#include "server/keyframe_fold_state.h"
#include "server/loop_closure_state.h"
#include "server/scan_encounter_state.h"

namespace anchormap {

// The loop-closure state in the snapshot format `snapshot_version` (server/snapshot_codec.h:
// 2 or later; older formats for the compatibility tests).
void PutLoopClosureState(ByteWriter* w, uint32_t snapshot_version, const LoopClosureState& state);
void PutScanEncounterState(ByteWriter* w, uint32_t snapshot_version,
                           const ScanEncounterState& state);
// A failed read latches in `r` (the caller checks r->failed()). The loop-closure state as
// the snapshot's format `snapshot_version` wrote it.
void GetLoopClosureState(ByteReader* r, uint32_t snapshot_version, LoopClosureState* state);
void GetScanEncounterState(ByteReader* r, uint32_t snapshot_version, ScanEncounterState* state);
// The folder's state (snapshot version 12 on; older snapshots hold none).
void PutKeyframeFolderState(ByteWriter* w, const KeyframeFolderState& state);
void GetKeyframeFolderState(ByteReader* r, KeyframeFolderState* state);

}  // namespace anchormap
