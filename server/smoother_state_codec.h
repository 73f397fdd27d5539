#pragma once
// The smoother's incremental state (common/solver/smoother_state.h) in a snapshot: every
// double bit for bit, in the server's byte codec (server/byte_codec.h). The solver knows no
// format; the snapshot codec (server/snapshot_codec.h) calls these for its version-2 section.
// The statistics' four time sums are this process's (as the server's update timings) and
// not written: a restored smoother counts them from 0, and two smoothers in one state write
// the same bytes.

#include "common/solver/smoother_state.h"
#include "server/byte_codec.h"

namespace anchormap {

void PutSmootherState(ByteWriter* w, const SmootherState& state);
// A failed read latches in `r` (the caller checks r->failed()).
void GetSmootherState(ByteReader* r, SmootherState* state);

}  // namespace anchormap
