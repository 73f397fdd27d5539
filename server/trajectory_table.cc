#include "server/trajectory_table.h"

#include <algorithm>
#include <set>

namespace anchormap {

int TrajectoryRecord::NearestIndex(int64_t utime) const {
  const auto after = std::lower_bound(utimes.begin(), utimes.end(), utime);
  if (after == utimes.begin()) return 0;
  if (after == utimes.end()) return num_keyframes() - 1;
  const auto before = std::prev(after);
  const int i = static_cast<int>(after - utimes.begin());
  return (utime - *before <= *after - utime) ? i - 1 : i;
}

Pose2 TrajectoryRecord::OdometryPoseAt(int64_t utime) const {
  if (utime <= utimes.front()) return odometry_poses.front();
  if (utime >= utimes.back()) return odometry_poses.back();
  const size_t i =
      static_cast<size_t>(std::lower_bound(utimes.begin(), utimes.end(), utime) - utimes.begin());
  if (utimes[i] == utime) return odometry_poses[i];
  const double fraction =
      static_cast<double>(utime - utimes[i - 1]) / static_cast<double>(utimes[i] - utimes[i - 1]);
  return Interpolate(odometry_poses[i - 1], odometry_poses[i], fraction);
}

TrajectoryRecord& TrajectoryTable::RecordFor(const Keyframe& keyframe, bool* created) {
  const auto key = std::make_pair(keyframe.robot, keyframe.trajectory_id);
  const auto it = index_.find(key);
  *created = it == index_.end();
  if (!*created) return records_[it->second];
  TrajectoryRecord record;
  record.robot = keyframe.robot;
  record.agent_trajectory_id = keyframe.trajectory_id;
  record.solver_id = static_cast<TrajectoryId>(records_.size());
  index_.emplace(key, records_.size());
  records_.push_back(std::move(record));
  pending_.emplace_back();
  return records_.back();
}

Status TrajectoryTable::Offer(Keyframe keyframe, std::vector<AdmittedKeyframe>* out) {
  bool created = false;
  TrajectoryRecord& record = RecordFor(keyframe, &created);
  const size_t record_index = static_cast<size_t>(record.solver_id);
  Pending& pending = pending_[record_index];
  if ((pending.started && keyframe.seq < pending.next_seq) || pending.held.count(keyframe.seq)) {
    return Status::Error(ErrorCode::kDuplicateSequence, keyframe.robot + " trajectory " +
                                                            std::to_string(keyframe.trajectory_id) +
                                                            " seq " + std::to_string(keyframe.seq));
  }
  const int32_t seq = keyframe.seq;
  pending.held.emplace(seq, std::move(keyframe));
  Drain(record_index, &pending, /*force=*/false, out);
  return Status::Ok();
}

void TrajectoryTable::FlushHeld(std::vector<AdmittedKeyframe>* out) {
  for (size_t i = 0; i < records_.size(); ++i) Drain(i, &pending_[i], /*force=*/true, out);
}

void TrajectoryTable::Drain(size_t record_index, Pending* pending, bool force,
                            std::vector<AdmittedKeyframe>* out) {
  TrajectoryRecord& record = records_[record_index];
  while (!pending->held.empty()) {
    const Keyframe& first = pending->held.begin()->second;
    const bool in_order = pending->started ? first.seq == pending->next_seq : first.seq == 0;
    bool over_limits = static_cast<int>(pending->held.size()) > options_.max_held;
    if (!over_limits) {
      const int64_t newest = pending->held.rbegin()->second.utime;
      const int64_t since = pending->started ? record.utimes.back() : first.utime;
      over_limits = 1e-6 * static_cast<double>(newest - since) > options_.max_hold_s;
    }
    if (!in_order && !force && !over_limits) break;
    Keyframe keyframe = std::move(pending->held.extract(pending->held.begin()).mapped());
    Admit(&record, pending, std::move(keyframe), out);
  }
}

void TrajectoryTable::Admit(TrajectoryRecord* record, Pending* pending, Keyframe keyframe,
                            std::vector<AdmittedKeyframe>* out) {
  AdmittedKeyframe admitted;
  const int32_t index = record->num_keyframes();
  admitted.key = PoseKey{record->solver_id, index};
  admitted.T_local_pose = keyframe.T_local_pose;
  admitted.new_trajectory = index == 0;
  if (index > 0) {
    admitted.previous = PoseKey{record->solver_id, index - 1};
    admitted.missing_steps = keyframe.seq - record->seqs.back() - 1;
    if (admitted.missing_steps == 0) {
      admitted.T_previous_this = keyframe.T_previous_this;
      admitted.T_previous_this_covariance = keyframe.T_previous_this_covariance;
    } else {
      // The agent's odometry frame is continuous within a session, so the two poses
      // give the motion across the gap; its noise grows with the steps it spans.
      admitted.bridged_gap = true;
      ++num_bridged_gaps_;
      admitted.T_previous_this = Between(record->odometry_poses.back(), keyframe.T_local_pose);
      admitted.T_previous_this_covariance = keyframe.T_previous_this_covariance *
                                            static_cast<double>(admitted.missing_steps + 1) *
                                            options_.gap_covariance_scale;
    }
  }
  record->seqs.push_back(keyframe.seq);
  record->utimes.push_back(keyframe.utime);
  record->odometry_poses.push_back(keyframe.T_local_pose);
  record->scans.push_back(std::move(keyframe.scan));
  pending->next_seq = keyframe.seq + 1;
  pending->started = true;
  ++num_keyframes_;
  out->push_back(admitted);
}

const TrajectoryRecord* TrajectoryTable::Find(const std::string& robot,
                                              int64_t agent_trajectory_id) const {
  const auto it = index_.find({robot, agent_trajectory_id});
  return it == index_.end() ? nullptr : &records_[it->second];
}

const TrajectoryRecord* TrajectoryTable::FindBySolverId(TrajectoryId solver_id) const {
  if (solver_id < 0 || static_cast<size_t>(solver_id) >= records_.size()) return nullptr;
  return &records_[static_cast<size_t>(solver_id)];
}

const TrajectoryRecord* TrajectoryTable::TrajectoryOfRobotAt(const std::string& robot,
                                                             int64_t utime) const {
  const TrajectoryRecord* latest_started = nullptr;
  const TrajectoryRecord* earliest = nullptr;
  for (const TrajectoryRecord& record : records_) {
    if (record.robot != robot || record.num_keyframes() == 0) continue;
    const int64_t start = record.utimes.front();
    if (start <= utime && (!latest_started || start > latest_started->utimes.front())) {
      latest_started = &record;
    }
    if (!earliest || start < earliest->utimes.front()) earliest = &record;
  }
  return latest_started ? latest_started : earliest;
}

int TrajectoryTable::num_robots() const {
  std::set<std::string> robots;
  for (const TrajectoryRecord& record : records_) robots.insert(record.robot);
  return static_cast<int>(robots.size());
}

size_t TrajectoryTable::num_held() const {
  size_t held = 0;
  for (const Pending& pending : pending_) held += pending.held.size();
  return held;
}

}  // namespace anchormap
