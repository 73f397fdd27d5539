#pragma once
// The options a journaled scan-match result was computed under, as one number (issue 13):
// the journal stamps every recorded match with it (RecordedMatch::options_fingerprint) and
// a restart reuses a recorded result only under the same fingerprint (MatchPool), so a
// server restarted with other matcher or source options matches again instead of taking
// results its options would not have produced.
//
// What it covers: every option of the two scan-matching sources (their matcher, window,
// reference, gating, candidate, budget and cooldown options; on/off), the match schedule's
// lag, and the smoother's options (the estimate the sources predict their windows from).
// Not: the worker count and the submap caches' memory budgets (results are bit for bit the
// same under any), nor the delivery, order and direct-encounter options. A field added to
// these option structs must be added here (docs/ARCHITECTURE.md "Scan sources in the
// journal"); size checks in the .cc fail the build until it is.

#include <cstdint>

#include "server/mapping_server.h"

namespace anchormap {

// FNV-1a 64 of the fields, never 0 (0 marks a record without a fingerprint).
uint64_t MatchOptionsFingerprint(const MappingServerOptions& options);

}  // namespace anchormap
