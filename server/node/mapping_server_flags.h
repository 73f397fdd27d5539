#pragma once
// The mapping server's own options (MappingServerOptions) as flags and config keys, registered
// once for both tools that run the server's logic, anchormap-server and anchormap-replay, so
// that the two spell, default and explain every option alike.

#include <string>

#include "common/util/options_loader.h"
#include "common/util/status.h"
#include "server/mapping_server.h"

namespace anchormap {

class MappingServerFlags {
 public:
  // Registers every option of `options` on `loader`, their current values as the defaults;
  // `help_prefix` starts each help text (anchormap-replay: "server: "). `options` must
  // outlive the loader's Parse() and Apply().
  MappingServerFlags(OptionsLoader* loader, MappingServerOptions* options,
                     const std::string& help_prefix = "");
  MappingServerFlags(const MappingServerFlags&) = delete;  // the loader keeps &formulation_
  MappingServerFlags& operator=(const MappingServerFlags&) = delete;

  // After the loader parsed: the options given as names (the formulation) into `options`.
  Status Apply() const;

 private:
  MappingServerOptions* options_;
  std::string formulation_;
};

}  // namespace anchormap
