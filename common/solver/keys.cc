#include "common/solver/keys.h"

namespace anchormap {

std::string Key::ToString() const {
  if (is_anchor()) return "anchor(" + std::to_string(trajectory) + ")";
  return "pose(" + std::to_string(trajectory) + "," + std::to_string(index) + ")";
}

}  // namespace anchormap
