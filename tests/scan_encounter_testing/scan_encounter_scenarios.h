#pragma once
// Scenarios for the scan encounters' tests, each a server with no sources of its own fed with
// robots' keyframes, and the hand-made candidates the tests offer between them:
// - the parallel tracks: R1 and R2 drive tracks 3 m apart, 40 keyframes each (keyframe i of each
//   at x = i m; no laser rays: the sources search nothing themselves, they only judge what they
//   are offered): R2[j] seen from R1[i] is (j - i, 3, 0);
// - three laps: three robots lap LoopWorld from three corners (real scans).

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/types/encounter.h"
#include "server/mapping_server.h"
#include "server/scan_encounters.h"

namespace anchormap::testing {

// The parallel tracks; with `seen_at_start`, R1 reports seeing R2 at their first keyframes,
// which joins them. Null when the server refused an input or the two are (not) in one frame
// against `seen_at_start`.
std::unique_ptr<MappingServer> DriveParallelTracks(bool seen_at_start);

// R2[j] seen from R1[i] on the parallel tracks, off the truth by `along_m` and `across_m`.
EncounterCandidate ParallelTracksCandidate(int32_t i, int32_t j, double along_m, double across_m,
                                           const Eigen::Matrix3d& covariance);

// Three robots lap LoopWorld from three corners.
class ThreeLaps {
 public:
  // The three robots' keyframes to a new server; with `r1_sees_r2`, R1 reports seeing R2 at
  // their first keyframes (R1 and R2 join). False when the server refused an input, or R1 and
  // R2 are (not) in one frame against `r1_sees_r2`, or R3 is in R1's.
  bool Drive(bool r1_sees_r2);

  // A direct encounter at the start: R1 sees robot `observed` (1: R2, 2: R3) where it stands.
  Encounter SeenByR1AtTheStart(size_t observed) const;

  // R3[j] seen from keyframe i of trajectory `from` (0: R1, 1: R2) as the world has it, R3
  // moved by `shift_world`.
  EncounterCandidate Candidate(int64_t from, int32_t i, int32_t j,
                               const Pose2& shift_world = Pose2()) const;

 protected:
  std::vector<std::vector<Pose2>> paths_;
  std::unique_ptr<MappingServer> server_;
};

}  // namespace anchormap::testing
