#include "agent/trajectory_id.h"

#include <random>

namespace anchormap {

int64_t DrawTrajectoryId() {
  std::random_device source;
  for (;;) {
    const uint64_t high = source();
    const uint64_t low = source();
    const int64_t id = static_cast<int64_t>(((high << 32) | (low & 0xffffffffu)) >> 1);
    if (id != 0) return id;
  }
}

}  // namespace anchormap
