#include "tests/merged_map_log.h"

#include "common/bus/lcm_log.h"
#include "common/bus/merged_map_assembler.h"

namespace anchormap {

Result<MergedMap> LastMergedMapInLog(const std::string& path) {
  LcmLogReader reader;
  if (Status s = reader.Open(path); !s.ok()) return s;
  MergedMapAssembler assembler;
  while (auto event = reader.Next()) {
    if (!assembler.IsMapChannel(event->channel)) continue;
    if (Status s = assembler.Accept(event->channel, event->data.data(), event->data.size());
        !s.ok()) {
      return Status::Error(s.code(), path + ": " + s.message());
    }
  }
  if (!assembler.map()) return Status::Error(path + ": no complete merged map");
  return *assembler.map();
}

}  // namespace anchormap
