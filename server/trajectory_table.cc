#include "server/trajectory_table.h"

#include <algorithm>
#include <set>

namespace anchormap {

void TrajectoryTable::ResumeAt(int64_t now_utime) {
  for (Pending& pending : pending_) {
    if (pending.gap_since >= 0) pending.gap_since = std::max(pending.gap_since, now_utime);
  }
}

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

TrajectoryRecord& TrajectoryTable::RecordFor(const Keyframe& keyframe, bool force_new,
                                             bool* created) {
  const TrajectoryName key{keyframe.robot, keyframe.trajectory_id};
  const auto it = index_.find(key);
  *created = force_new || it == index_.end();
  if (!*created) return records_[it->second];
  TrajectoryRecord record;
  record.robot = keyframe.robot;
  record.agent_trajectory_id = keyframe.trajectory_id;
  record.solver_id = TrajectoryId(static_cast<int64_t>(records_.size()));
  index_[key] = records_.size();
  records_.push_back(std::move(record));
  pending_.emplace_back();
  return records_.back();
}

Status TrajectoryTable::Offer(Keyframe keyframe, int64_t now_utime,
                              std::vector<AdmittedKeyframe>* out) {
  bool created = false;
  TrajectoryRecord* record = &RecordFor(keyframe, /*force_new=*/false, &created);
  const auto name = [&] {
    return keyframe.robot + " trajectory " + std::to_string(keyframe.trajectory_id) + " seq " +
           std::to_string(keyframe.seq);
  };
  const auto admitted = std::lower_bound(record->seqs.begin(), record->seqs.end(), keyframe.seq);
  if (admitted != record->seqs.end() && *admitted == keyframe.seq) {
    const size_t i = static_cast<size_t>(admitted - record->seqs.begin());
    // A first keyframe unlike the one admitted: an agent restarted with a reused id. It
    // is a new trajectory (the old one keeps what it has), not a stream of duplicates.
    if (keyframe.seq != 0 || record->utimes[i] == keyframe.utime) {
      return Status::Error(ErrorCode::kDuplicateSequence, name());
    }
    ++num_reused_ids_;
    record = &RecordFor(keyframe, /*force_new=*/true, &created);
  }
  const size_t record_index = static_cast<size_t>(record->solver_id.value());
  Pending& pending = pending_[record_index];
  if (pending.held.count(keyframe.seq)) {
    return Status::Error(ErrorCode::kDuplicateSequence, name());
  }
  if (pending.started && keyframe.seq < pending.next_seq) {
    return Status::Error(ErrorCode::kLateSequence, name() + " came after its gap was bridged");
  }
  // The count of relayed encounters never decreases along a trajectory (the agent's relay
  // sequence only grows): compared with the nearest keyframes known before and after this
  // one (those are consistent with each other already).
  const auto later = pending.held.upper_bound(keyframe.seq);
  const int32_t at_least = later != pending.held.begin()
                               ? std::prev(later)->second.encounters_relayed
                               : (pending.started ? pending.admitted_encounters_relayed : 0);
  if (keyframe.encounters_relayed < at_least ||
      (later != pending.held.end() &&
       keyframe.encounters_relayed > later->second.encounters_relayed)) {
    return Status::Error(ErrorCode::kBadSequence, name() + ": encounters_relayed " +
                                                      std::to_string(keyframe.encounters_relayed) +
                                                      " goes backwards along the trajectory");
  }
  const int32_t seq = keyframe.seq;
  pending.held.emplace(seq, std::move(keyframe));
  Drain(record_index, &pending, /*force=*/false, now_utime, out);
  return Status::Ok();
}

void TrajectoryTable::Poll(int64_t now_utime, std::vector<AdmittedKeyframe>* out) {
  for (size_t i = 0; i < records_.size(); ++i) {
    if (!pending_[i].held.empty()) Drain(i, &pending_[i], /*force=*/false, now_utime, out);
  }
}

void TrajectoryTable::FlushHeld(std::vector<AdmittedKeyframe>* out) {
  for (size_t i = 0; i < records_.size(); ++i) {
    Drain(i, &pending_[i], /*force=*/true, /*now_utime=*/0, out);
  }
}

std::vector<std::pair<int32_t, int32_t>> TrajectoryTable::MissingRanges(
    TrajectoryId solver_id) const {
  std::vector<std::pair<int32_t, int32_t>> ranges;
  const std::optional<size_t> index = IndexOf(solver_id);
  if (!index) return ranges;
  const Pending& pending = pending_[*index];
  int32_t expected = pending.started ? pending.next_seq : 0;
  for (const auto& [seq, keyframe] : pending.held) {
    if (seq > expected) ranges.emplace_back(expected, seq - 1);
    expected = seq + 1;
  }
  return ranges;
}

int32_t TrajectoryTable::NextSeq(TrajectoryId solver_id) const {
  const std::optional<size_t> index = IndexOf(solver_id);
  if (!index) return 0;
  const Pending& pending = pending_[*index];
  return pending.started ? pending.next_seq : 0;
}

void TrajectoryTable::Drain(size_t record_index, Pending* pending, bool force, int64_t now_utime,
                            std::vector<AdmittedKeyframe>* out) {
  TrajectoryRecord& record = records_[record_index];
  while (!pending->held.empty()) {
    const Keyframe& first = pending->held.begin()->second;
    const bool in_order = pending->started ? first.seq == pending->next_seq : first.seq == 0;
    if (in_order) {
      pending->gap_since = -1;
    } else if (pending->gap_since < 0) {
      pending->gap_since = now_utime;
    }
    const bool over_limits =
        static_cast<int>(pending->held.size()) > options_.max_held ||
        (!in_order &&
         1e-6 * static_cast<double>(now_utime - pending->gap_since) > options_.max_hold_s);
    if (!in_order && !force && !over_limits) break;
    Keyframe keyframe = std::move(pending->held.extract(pending->held.begin()).mapped());
    pending->gap_since = -1;  // a later gap opens now (in the next turn)
    Admit(&record, pending, std::move(keyframe), out);
  }
  if (pending->held.empty()) pending->gap_since = -1;
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
  pending->admitted_encounters_relayed = keyframe.encounters_relayed;
  pending->started = true;
  ++num_keyframes_;
  out->push_back(admitted);
}

const TrajectoryRecord* TrajectoryTable::Find(const TrajectoryName& name) const {
  const auto it = index_.find(name);
  return it == index_.end() ? nullptr : &records_[it->second];
}

const TrajectoryRecord* TrajectoryTable::FindBySolverId(TrajectoryId solver_id) const {
  const std::optional<size_t> index = IndexOf(solver_id);
  return index ? &records_[*index] : nullptr;
}

std::optional<size_t> TrajectoryTable::IndexOf(TrajectoryId solver_id) const {
  // Solver ids are dense, in order of arrival: the id is the record's index.
  const int64_t index = solver_id.value();
  if (index < 0 || static_cast<size_t>(index) >= records_.size()) return std::nullopt;
  return static_cast<size_t>(index);
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
