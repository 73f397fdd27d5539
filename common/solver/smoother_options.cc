#include "common/solver/smoother_options.h"

namespace anchormap {

SmootherOptions ServerModeOptions() {
  SmootherOptions options;
  options.batch_every_updates = 0;
  options.relinearize_threshold = 0.01;
  options.partial_merges = true;
  // With the correction, every corrected update solves with R several times (the cost on
  // city10000): reordering at 1.5x fill keeps R near the ordering's own fill. Measured
  // (docs/ARCHITECTURE.md): city10000 35.9 -> 20.9 s CPU, 30 -> 90 batch steps of at most
  // 0.16 s; 1.2 and 1.1 no faster (more batch steps).
  options.batch_when_fill_grows = 1.5;
  // 100 robots x 180 s: fill batch steps' factorisation ~35 % cheaper, update p99 421 -> 297,
  // 394 -> 331, 398 -> 354 ms on seeds 2 / 1 / 3 (docs/ARCHITECTURE.md, fill22).
  options.latest_poses_last = false;
  return options;
}

SmootherOptions ServerModeWithCorrectionOptions() {
  SmootherOptions options = ServerModeOptions();
  options.correction_tolerance = 1e-4;
  options.correction_iterations = 5;
  options.relinearize_when_correction_stalls = true;
  options.correction_cg_iterations = 50;
  // correction_local_hops stays 0: on, it cut 20 robots' solver time by ~9 % but cost
  // 100 robots up to 10 % CPU (docs/ARCHITECTURE.md, corr23).
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
