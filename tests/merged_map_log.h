#pragma once
// The last complete merged map a run published, read back from its output LCM log (the
// header and chunks, or the single message, put together by MergedMapAssembler): what the
// system tests check a whole run by.

#include <string>

#include "common/types/map_outputs.h"
#include "common/util/status.h"

namespace anchormap {

// An error when the log does not open, a map message does not decode, or no map is complete.
Result<MergedMap> LastMergedMapInLog(const std::string& path);

}  // namespace anchormap
