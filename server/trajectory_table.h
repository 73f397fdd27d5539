#pragma once
// The server's record of robot trajectories: (robot, agent trajectory id) -> the solver's
// TrajectoryId, each trajectory's accepted keyframes (time, odometry pose, scan) in
// solver-index order, and the sequence-number checks that decide when a keyframe may
// enter the graph.
//
// A seq 0 keyframe unlike the admitted seq 0 (another time) comes from an agent restarted
// with a reused trajectory id: it starts a new record (a new solver trajectory) and
// (robot, id) names that one from then on; the old record keeps its keyframes.
// Sequence rules: seq must be new for its trajectory (a seq admitted before is refused as
// kDuplicateSequence; one whose gap was bridged before it came as kLateSequence). The next
// expected seq enters at once; a later one waits (the bus may reorder or lose one; the
// server asks the agent to resend what is missing, MissingRanges()) until the gap fills,
// or until the gap has stayed open max_hold_s on the caller's clock (wall time online, data
// time offline) or the waiting list holds more than max_held keyframes: then, as a last
// resort, the gap is bridged, the odometry poses of the two keyframes around it giving the
// measurement and the waiting keyframe's delta covariance scaled by the number of missing
// steps giving its noise. A trajectory first seen at seq > 0 (a server started late)
// starts at its lowest seq when the same limits run out. A keyframe whose count of relayed
// encounters (Keyframe::encounters_relayed) is below an earlier keyframe's or above a later
// one's is refused (kBadSequence): the count never decreases along a trajectory.

#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/solver/keys.h"
#include "common/types/keyframe.h"
#include "common/types/trajectory_name.h"
#include "common/util/reject_counter.h"
#include "common/util/status.h"

namespace anchormap {

struct TrajectoryTableOptions {
  // Bounds on keyframes waiting for a missing sequence number (per trajectory): at most
  // max_held keyframes, for at most max_hold_s on the caller's clock since the gap opened.
  int max_held = 1000;
  double max_hold_s = 10.0;
  // A bridged gap's covariance: the delta covariance times (missing steps + 1) times this.
  double gap_covariance_scale = 2.0;

  Status Validate() const {
    if (max_held < 1) return Status::Error("table.max_held must be >= 1");
    if (!(max_hold_s >= 0)) return Status::Error("table.max_hold_s must be >= 0");
    if (!(gap_covariance_scale >= 1))
      return Status::Error("table.gap_covariance_scale must be >= 1");
    return Status::Ok();
  }
};

// One trajectory's accepted keyframes, index i = solver PoseKey index i.
struct TrajectoryRecord {
  std::string robot;
  int64_t agent_trajectory_id = 0;  // with `robot`, the trajectory's name on the bus
  TrajectoryId solver_id;
  TrajectoryName name() const { return {robot, agent_trajectory_id}; }
  std::vector<int32_t> seqs;
  std::vector<int64_t> utimes;
  std::vector<Pose2> odometry_poses;  // T_local_pose as the agent sent it
  std::vector<LaserScan> scans;

  int num_keyframes() const { return static_cast<int>(utimes.size()); }
  // The index whose time is nearest to `utime` (precondition: at least one keyframe).
  int NearestIndex(int64_t utime) const;
  // The odometry pose at `utime`, interpolated between the keyframes around it (linear in
  // x, y, shortest in theta); the end keyframe's pose outside the covered time.
  Pose2 OdometryPoseAt(int64_t utime) const;
};

// A keyframe cleared to enter the graph, with the between factor to add (none for the
// first keyframe of a trajectory).
struct AdmittedKeyframe {
  PoseKey key;
  Pose2 T_local_pose;
  std::optional<PoseKey> previous;
  Pose2 T_previous_this;
  Eigen::Matrix3d T_previous_this_covariance = Eigen::Matrix3d::Identity();
  bool bridged_gap = false;
  int missing_steps = 0;
  bool new_trajectory = false;
};

class TrajectoryTable {
 public:
  explicit TrajectoryTable(const TrajectoryTableOptions& options = {}) : options_(options) {}

  // Offers a keyframe at `now_utime` (the clock of the hold rule); returns the keyframes
  // (this one and/or waiting ones) that may now enter the graph, in order, already
  // recorded here; or why it is refused. Without `now_utime`, the keyframe's own time.
  Status Offer(Keyframe keyframe, int64_t now_utime, std::vector<AdmittedKeyframe>* out);
  Status Offer(Keyframe keyframe, std::vector<AdmittedKeyframe>* out) {
    const int64_t now_utime = keyframe.utime;
    return Offer(std::move(keyframe), now_utime, out);
  }
  // Bridges the gaps that have stayed open longer than max_hold_s at `now_utime`.
  void Poll(int64_t now_utime, std::vector<AdmittedKeyframe>* out);
  // Admits every waiting keyframe, bridging gaps (end of input).
  void FlushHeld(std::vector<AdmittedKeyframe>* out);
  // A restarted server resumes at `now_utime`: open gaps count their hold from then at the
  // earliest (the server's downtime and replay are not the agents' delay).
  void ResumeAt(int64_t now_utime);

  // The missing sequence numbers below the highest waiting one of trajectory `solver_id`
  // (empty when nothing waits), as inclusive ranges.
  std::vector<std::pair<int32_t, int32_t>> MissingRanges(TrajectoryId solver_id) const;
  // Every seq below this is admitted or given up (bridged) in trajectory `solver_id`.
  int32_t NextSeq(TrajectoryId solver_id) const;

  const TrajectoryRecord* Find(const TrajectoryName& name) const;
  const TrajectoryRecord* FindBySolverId(TrajectoryId solver_id) const;
  // The robot's trajectory (session) at `utime`: the latest one that started at or before
  // `utime`, else its earliest; nullptr for a robot never seen.
  const TrajectoryRecord* TrajectoryOfRobotAt(const std::string& robot, int64_t utime) const;

  const std::deque<TrajectoryRecord>& records() const { return records_; }
  int num_robots() const;
  int64_t num_keyframes() const { return num_keyframes_; }
  int64_t num_bridged_gaps() const { return num_bridged_gaps_; }
  // Trajectory ids reused by a restarted agent (a seq 0 unlike the admitted one): each
  // started a new record, to which (robot, id) refers from then on.
  int64_t num_reused_ids() const { return num_reused_ids_; }
  size_t num_held() const;

  // The snapshot codec (server/snapshot_codec.cc) reads and restores the private state.
  friend struct SnapshotAccess;

 private:
  struct Pending {
    int32_t next_seq = 0;
    bool started = false;  // at least one keyframe admitted
    // The last admitted keyframe's count of relayed encounters: a later one may not be lower.
    int32_t admitted_encounters_relayed = 0;
    std::map<int32_t, Keyframe> held;
    int64_t gap_since = -1;  // clock when the current gap opened; -1: no gap
  };
  // The keyframe's record; a new one when none exists or `force_new` (a reused id).
  TrajectoryRecord& RecordFor(const Keyframe& keyframe, bool force_new, bool* created);
  // The position of `solver_id`'s record, if it has one.
  std::optional<size_t> IndexOf(TrajectoryId solver_id) const;
  // Moves waiting keyframes into the graph while possible (or forced).
  void Drain(size_t record_index, Pending* pending, bool force, int64_t now_utime,
             std::vector<AdmittedKeyframe>* out);
  void Admit(TrajectoryRecord* record, Pending* pending, Keyframe keyframe,
             std::vector<AdmittedKeyframe>* out);

  TrajectoryTableOptions options_;
  std::deque<TrajectoryRecord> records_;  // stable addresses; solver id = position
  std::vector<Pending> pending_;          // parallel to records_
  std::map<TrajectoryName, size_t> index_;
  int64_t num_keyframes_ = 0;
  int64_t num_bridged_gaps_ = 0;
  int64_t num_reused_ids_ = 0;
};

}  // namespace anchormap
