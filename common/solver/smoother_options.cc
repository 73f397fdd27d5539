#include "common/solver/smoother_options.h"

namespace anchormap {

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
