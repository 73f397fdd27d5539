#include "common/solver/smoother_options.h"

namespace anchormap {

SmootherOptions ServerModeOptions() {
  SmootherOptions options;
  options.batch_every_updates = 0;
  options.relinearize_threshold = 0.01;
  options.partial_merges = true;
  return options;
}

const char* ToString(Formulation formulation) {
  switch (formulation) {
    case Formulation::kRelative:
      return "relative";
    case Formulation::kGlobal:
      return "global";
    case Formulation::kGlobalMoved:
      return "global-moved";
  }
  return "?";
}

std::optional<Formulation> ParseFormulation(const std::string& text) {
  if (text == "relative") return Formulation::kRelative;
  if (text == "global") return Formulation::kGlobal;
  if (text == "global-moved") return Formulation::kGlobalMoved;
  return std::nullopt;
}

}  // namespace anchormap
