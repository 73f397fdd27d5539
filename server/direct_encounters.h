#pragma once
// The encounter source for direct encounters reported on the bus (one robot observed
// another at time t). Each is tied to keyframes: the observer's and the observed robot's
// keyframes nearest in time to t. The measurement is corrected for the motion between t
// and those keyframes, taken from the keyframes' odometry poses interpolated to t in each
// trajectory's local frame:
//   T_ka_kb = T_ka_ta (+) T_ta_tb (+) T_tb_kb
// and its covariance is propagated through the compositions and inflated by a motion
// noise model for the corrections. An encounter waits until both robots have a keyframe
// at or after t (the agents force one there), for at most max_wait_s of data time.

#include <cstdint>
#include <deque>
#include <optional>
#include <string>

#include "common/geometry/motion_noise.h"
#include "common/util/status.h"
#include "server/encounter_source.h"
#include "server/trajectory_table.h"

namespace anchormap {

struct DirectEncounterOptions {
  static MotionNoise DefaultInflation() {
    MotionNoise noise;
    noise.xy_base_m = 0.005;
    noise.xy_per_m = 0.05;
    noise.theta_base_rad = 0.002;
    noise.theta_per_rad = 0.05;
    noise.theta_per_m = 0.02;
    return noise;
  }

  // Longest wait (data time) for both robots' keyframes or for an unknown robot.
  double max_wait_s = 30.0;
  // Encounters waiting at once; the oldest is dropped beyond this (kQueueFull).
  int max_pending = 1000;
  // The nearest keyframe must be this close in time, or the encounter is refused.
  double max_time_offset_s = 1.0;
  // Added to an encounter for the motion between each keyframe and the encounter time
  // (MotionNoise of that motion); the base terms cover clock offsets.
  MotionNoise inflation = DefaultInflation();

  Status Validate() const {
    if (!(max_wait_s >= 0)) return Status::Error("direct.max_wait_s must be >= 0");
    if (max_pending < 1) return Status::Error("direct.max_pending must be >= 1");
    if (!(max_time_offset_s > 0)) return Status::Error("direct.max_time_offset_s must be > 0");
    return inflation.Validate("direct.inflation", /*positive_base=*/false);
  }
};

// Ties one encounter to the keyframes of `observer` and `observed` nearest to its time.
// Returns the constraint, or why it cannot be tied (kNoKeyframeNearTime).
Result<EncounterConstraint> TieEncounter(const Encounter& encounter,
                                         const TrajectoryRecord& observer,
                                         const TrajectoryRecord& observed,
                                         const DirectEncounterOptions& options);

class DirectEncounters : public EncounterSource {
 public:
  explicit DirectEncounters(const DirectEncounterOptions& options = {}) : options_(options) {}

  std::string name() const override { return "direct"; }
  void OnEncounterMessage(const Encounter& encounter, const GraphView& graph,
                          EncounterSourceOutput* out) override;
  void OnKeyframeAdded(PoseKey key, const GraphView& graph, EncounterSourceOutput* out) override;
  void Poll(int64_t now_utime, const GraphView& graph, EncounterSourceOutput* out) override;
  void Flush(const GraphView& graph, EncounterSourceOutput* out) override;
  size_t pending() const override { return pending_.size(); }
  // Ties encounters by keyframe times only (the table), never by the estimate.
  bool ReadsEstimate() const override { return false; }

  // The snapshot codec (server/snapshot_codec.cc) reads and restores the private state.
  friend struct SnapshotAccess;

 private:
  // Ties every waiting encounter whose keyframes are there; refuses those that waited too
  // long (or all unresolved ones when `flush`).
  void Resolve(const TrajectoryTable& table, bool flush, EncounterSourceOutput* out);

  DirectEncounterOptions options_;
  std::deque<Encounter> pending_;
  int64_t now_utime_ = 0;
};

}  // namespace anchormap
