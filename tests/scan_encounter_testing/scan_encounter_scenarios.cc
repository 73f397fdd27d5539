#include "tests/scan_encounter_testing/scan_encounter_scenarios.h"

#include <string>

#include "server/relative_pose.h"
#include "tests/scan_testing/scan_scenarios.h"
#include "tests/testing/straight_keyframes.h"

namespace anchormap::testing {

std::unique_ptr<MappingServer> DriveParallelTracks(bool seen_at_start) {
  MappingServerOptions options;
  options.loop_closures = false;
  options.scan_encounters = false;
  auto server = std::make_unique<MappingServer>(options);
  for (int32_t seq = 0; seq < 40; ++seq) {
    if (!server->OnKeyframe(StraightKeyframe("R1", 1, seq, 0)).ok()) return nullptr;
    if (!server->OnKeyframe(StraightKeyframe("R2", 2, seq, 0)).ok()) return nullptr;
    if (seen_at_start && seq == 0) {
      Encounter seen;
      seen.utime = 1'000'000;
      seen.observer = "R1";
      seen.observer_trajectory_id = 1;
      seen.observed = "R2";
      seen.T_observer_observed = Pose2(0.0, 3.0, 0.0);
      seen.covariance = Eigen::Vector3d(1e-4, 1e-4, 1e-6).asDiagonal();
      if (!server->OnEncounter(seen).ok()) return nullptr;
    }
  }
  server->Flush();
  if (InOneFrame(server->smoother(), TrajectoryId(0), TrajectoryId(1)) != seen_at_start) {
    return nullptr;
  }
  return server;
}

EncounterCandidate ParallelTracksCandidate(int32_t i, int32_t j, double along_m, double across_m,
                                           const Eigen::Matrix3d& covariance) {
  EncounterCandidate c;
  c.a = {TrajectoryId(0), i};
  c.b = {TrajectoryId(1), j};
  c.T_a_b = Pose2(j - i + along_m, 3.0 + across_m, 0.0);
  c.covariance = covariance;
  c.utime = 1'000'000 + 1'000'000 * int64_t{j};
  return c;
}

bool ThreeLaps::Drive(bool r1_sees_r2) {
  paths_ = {LoopWorldLap(0, 60), LoopWorldLap(50, 60), LoopWorldLap(25, 60)};
  MappingServerOptions options;
  options.loop_closures = false;
  options.scan_encounters = false;
  server_ = std::make_unique<MappingServer>(options);
  const OdometryNoise noise{0.002, 0.001};
  std::vector<std::vector<Keyframe>> keyframes;
  for (size_t r = 0; r < paths_.size(); ++r) {
    keyframes.push_back(DriveKeyframes(LoopWorld(), paths_[r], "R" + std::to_string(r + 1),
                                       static_cast<int64_t>(r + 1), 1'000'000, noise, 21 + r));
  }
  for (size_t i = 0; i < paths_[0].size(); ++i) {
    for (const std::vector<Keyframe>& k : keyframes) {
      if (!server_->OnKeyframe(k[i]).ok()) return false;
    }
    if (i == 0 && r1_sees_r2) {
      if (!server_->OnEncounter(SeenByR1AtTheStart(1)).ok()) return false;
    }
  }
  server_->Flush();
  return InOneFrame(server_->smoother(), TrajectoryId(0), TrajectoryId(1)) == r1_sees_r2 &&
         !InOneFrame(server_->smoother(), TrajectoryId(0), TrajectoryId(2));
}

Encounter ThreeLaps::SeenByR1AtTheStart(size_t observed) const {
  Encounter seen;
  seen.utime = 1'000'000;
  seen.observer = "R1";
  seen.observer_trajectory_id = 1;
  seen.observed = "R" + std::to_string(observed + 1);
  seen.T_observer_observed = Compose(paths_[0][0].Inverse(), paths_[observed][0]);
  seen.covariance = Eigen::Vector3d(1e-4, 1e-4, 1e-6).asDiagonal();
  return seen;
}

EncounterCandidate ThreeLaps::Candidate(int64_t from, int32_t i, int32_t j,
                                        const Pose2& shift_world) const {
  EncounterCandidate c;
  c.a = {TrajectoryId(from), i};
  c.b = {TrajectoryId(2), j};
  c.T_a_b = Compose(paths_[static_cast<size_t>(from)][static_cast<size_t>(i)].Inverse(),
                    Compose(shift_world, paths_[2][static_cast<size_t>(j)]));
  c.covariance = Eigen::Vector3d(4e-4, 4e-4, 2.5e-5).asDiagonal();
  c.utime = 1'000'000 + 500'000 * int64_t{j};
  return c;
}

}  // namespace anchormap::testing
