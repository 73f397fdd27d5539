#include "common/solver/keys.h"

namespace anchormap {

std::string Key::ToString() const {
  if (is_anchor()) return "anchor(" + std::to_string(trajectory.value()) + ")";
  return "pose(" + std::to_string(trajectory.value()) + "," + std::to_string(index) + ")";
}

}  // namespace anchormap
