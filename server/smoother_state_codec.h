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

// In the snapshot format `snapshot_version` (server/snapshot_codec.h): version 8 adds the
// uncorrected factors; older ones read as none (before version 8 the skip test's bound,
// `innovation`, covered them; written in an older format, it is infinite if there are any).
// Version 11 adds the local corrections' moves (correction_local_hops); older ones read as
// none, and written in an older format the bound is infinite if there are any. A version-10
// snapshot of a server that ran the then opt-in local correction lacks them: restored, its
// first skip test may leave out the moved factors' terms (the next whole-map correction
// clears them). Version 12 adds the reduced graph's counts (aliases, measurements inside one
// node; Smoother::ImportState checks them against the graph's); older ones read as 0, as no
// server that folded keyframes wrote them.
void PutSmootherState(ByteWriter* w, uint32_t snapshot_version, const SmootherState& state);
// A failed read latches in `r` (the caller checks r->failed()).
void GetSmootherState(ByteReader* r, uint32_t snapshot_version, SmootherState* state);

}  // namespace anchormap
