#include "tools/bench/simulated_keyframes.h"

#include <memory>

#include "tools/sim/simulator.h"

namespace anchormap {

Status SimulateKeyframes(const sim::SimOptions& options, double keyframe_period_s,
                         std::vector<SimulatedKeyframe>* keyframes) {
  if (Status status = options.Validate(); !status.ok()) return status;
  std::unique_ptr<sim::Simulator> simulator;
  if (Status status = sim::Simulator::Create(options, &simulator); !status.ok()) return status;
  keyframes->clear();
  std::vector<double> last_keyframe_s(static_cast<size_t>(simulator->num_robots()), -1e9);
  while (!simulator->Done()) {
    sim::SimFrame frame = simulator->Step();
    if (!frame.has_scans) continue;
    const double t = 1e-6 * static_cast<double>(frame.utime - options.start_utime);
    for (int r = 0; r < simulator->num_robots(); ++r) {
      if (t - last_keyframe_s[static_cast<size_t>(r)] < keyframe_period_s) continue;
      last_keyframe_s[static_cast<size_t>(r)] = t;
      keyframes->push_back(
          {r, frame.scans[static_cast<size_t>(r)], simulator->robot(r).T_world_body(), t});
    }
  }
  return Status::Ok();
}

}  // namespace anchormap
