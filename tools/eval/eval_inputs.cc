#include "tools/eval/eval_inputs.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <numeric>

#include "bot_core/pose_t.hpp"
#include "common/bus/channels.h"
#include "common/bus/lcm_log.h"
#include "common/bus/map_codec.h"
#include "common/bus/merged_map_assembler.h"
#include "common/io/trajectory_file.h"

namespace anchormap {
namespace {

void SortByTime(StampedTrajectory* poses) {
  std::stable_sort(poses->begin(), poses->end(),
                   [](const StampedPose2& a, const StampedPose2& b) { return a.utime < b.utime; });
}

int FindRoot(std::vector<int>* parent, int i) {
  while ((*parent)[i] != i) i = (*parent)[i] = (*parent)[(*parent)[i]];
  return i;
}

// Numbers the anchored trajectories' groups (see EstimatedTrajectory::group).
void AssignGroups(const merged_map_t& map, MapEstimate* estimate) {
  auto& trajectories = estimate->trajectories;
  const int n = static_cast<int>(trajectories.size());
  std::vector<int> parent(n);
  std::iota(parent.begin(), parent.end(), 0);
  // Trajectory ids are unique per robot only: a link names both.
  const auto index_of = [&](const std::string& robot, int64_t id) {
    for (int i = 0; i < n; ++i) {
      if (trajectories[i].robot == robot && trajectories[i].trajectory_id == id) return i;
    }
    return -1;
  };
  if (map.encounters.empty()) {
    int first = -1;
    for (int i = 0; i < n; ++i) {
      if (!trajectories[i].anchored) continue;
      if (first < 0) first = i;
      parent[FindRoot(&parent, i)] = FindRoot(&parent, first);
    }
  }
  for (const encounter_link_t& link : map.encounters) {
    const int a = index_of(link.robot_a, link.trajectory_a);
    const int b = index_of(link.robot_b, link.trajectory_b);
    if (a < 0 || b < 0 || !trajectories[a].anchored || !trajectories[b].anchored) continue;
    parent[FindRoot(&parent, a)] = FindRoot(&parent, b);
  }
  std::map<int, size_t> poses_by_root;
  for (int i = 0; i < n; ++i) {
    if (trajectories[i].anchored)
      poses_by_root[FindRoot(&parent, i)] += trajectories[i].poses.size();
  }
  std::vector<std::pair<size_t, int>> order;  // (-poses, root) sorts largest first
  for (const auto& [root, poses] : poses_by_root) order.push_back({poses, root});
  std::stable_sort(order.begin(), order.end(),
                   [](const auto& a, const auto& b) { return a.first > b.first; });
  std::map<int, int> group_of_root;
  for (size_t g = 0; g < order.size(); ++g) group_of_root[order[g].second] = static_cast<int>(g);
  for (int i = 0; i < n; ++i) {
    trajectories[i].group = trajectories[i].anchored ? group_of_root[FindRoot(&parent, i)] : -1;
  }
  estimate->num_groups = static_cast<int>(order.size());
}

}  // namespace

bool IsLcmLogFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  unsigned char magic[4] = {0, 0, 0, 0};
  in.read(reinterpret_cast<char*>(magic), 4);
  return in.gcount() == 4 && magic[0] == 0xED && magic[1] == 0xA1 && magic[2] == 0xDA &&
         magic[3] == 0x01;
}

void ConvertMergedMap(const merged_map_t& map, MapEstimate* estimate) {
  estimate->update = map.update;
  estimate->utime = map.utime;
  estimate->trajectories.clear();
  for (const trajectory_t& t : map.trajectories) {
    EstimatedTrajectory trajectory;
    trajectory.robot = t.robot;
    trajectory.trajectory_id = t.trajectory_id;
    trajectory.anchored = t.anchored;
    const size_t n = std::min(
        {static_cast<size_t>(std::max(t.num_poses, 0)), t.pose_utimes.size(), t.poses.size()});
    for (size_t i = 0; i < n; ++i) {
      if (t.poses[i].size() != 3) {
        ++estimate->invalid_poses;
        continue;
      }
      const Pose2 pose(t.poses[i][0], t.poses[i][1], t.poses[i][2]);
      if (!pose.IsFinite()) {
        ++estimate->invalid_poses;
        continue;
      }
      trajectory.poses.push_back({t.pose_utimes[i], pose});
    }
    SortByTime(&trajectory.poses);
    estimate->trajectories.push_back(std::move(trajectory));
  }
  AssignGroups(map, estimate);
}

Status ReadMapEstimate(const std::string& path, const std::string& channel,
                       const std::string& tum_robot, MapEstimate* estimate,
                       Authenticator* authenticator, const std::string& header_channel,
                       const std::string& chunks_channel) {
  *estimate = MapEstimate();
  if (!IsLcmLogFile(path)) {
    EstimatedTrajectory trajectory;
    trajectory.robot = tum_robot;
    if (Status s = ReadTrajectoryFile(path, &trajectory.poses); !s.ok()) {
      return Status::Error(s.message() + " (neither an LCM log nor a TUM trajectory file)");
    }
    SortByTime(&trajectory.poses);
    estimate->trajectories.push_back(std::move(trajectory));
    return Status::Ok();
  }
  LcmLogReader reader;
  if (Status s = reader.Open(path); !s.ok()) return s;
  MergedMapAssembler assembler({header_channel, chunks_channel, channel});
  while (auto event = reader.Next()) {
    if (!assembler.IsMapChannel(event->channel)) continue;
    ++estimate->maps_seen;
    if (!OpenLoggedEvent(authenticator, &*event).ok()) {
      ++estimate->unauthenticated;
      continue;
    }
    if (!assembler.Accept(event->channel, event->data.data(), event->data.size()).ok()) {
      ++estimate->undecodable;
    }
  }
  if (!assembler.map()) {
    return Status::Error(
        path + ": no complete merged map on channel " + channel + " or " + header_channel + " + " +
        chunks_channel + " (" + std::to_string(estimate->maps_seen) + " messages" +
        (authenticator
             ? ", " + std::to_string(estimate->unauthenticated) + " refused by the key check"
             : std::string()) +
        ")");
  }
  const int64_t seen = estimate->maps_seen, undecodable = estimate->undecodable;
  const int64_t unauthenticated = estimate->unauthenticated;
  // The assembled map through the wire type, which ConvertMergedMap validates.
  const std::vector<uint8_t> bytes = EncodeMergedMap(*assembler.map());
  merged_map_t last;
  last.decode(bytes.data(), 0, static_cast<int>(bytes.size()));
  ConvertMergedMap(last, estimate);
  estimate->maps_seen = seen;
  estimate->undecodable = undecodable;
  estimate->unauthenticated = unauthenticated;
  return Status::Ok();
}

Status ReadPoseChannels(const std::string& path, const std::string& suffix,
                        std::map<std::string, StampedTrajectory>* by_robot, int64_t* undecodable) {
  by_robot->clear();
  LcmLogReader reader;
  if (Status s = reader.Open(path); !s.ok()) return s;
  while (auto event = reader.Next()) {
    const std::string& channel = event->channel;
    if (channel.size() <= suffix.size() ||
        channel.compare(channel.size() - suffix.size(), suffix.size(), suffix) != 0) {
      continue;
    }
    const auto pose = DecodeAs<bot_core::pose_t>(*event);
    const Pose2 pose2 = pose ? Pose2(pose->pos[0], pose->pos[1],
                                     YawOfQuaternion(pose->orientation[0], pose->orientation[1],
                                                     pose->orientation[2], pose->orientation[3]))
                             : Pose2();
    if (!pose || !pose2.IsFinite()) {
      ++*undecodable;
      continue;
    }
    (*by_robot)[channel.substr(0, channel.size() - suffix.size())].push_back({pose->utime, pose2});
  }
  for (auto& [robot, poses] : *by_robot) SortByTime(&poses);
  return Status::Ok();
}

Status ReadReferences(const std::string& path, const std::string& tum_robot,
                      ReferenceSet* references) {
  *references = ReferenceSet();
  if (!IsLcmLogFile(path)) {
    StampedTrajectory poses;
    if (Status s = ReadTrajectoryFile(path, &poses); !s.ok()) {
      return Status::Error(s.message() + " (neither an LCM log nor a TUM trajectory file)");
    }
    SortByTime(&poses);
    references->by_robot[tum_robot] = std::move(poses);
    references->source_by_robot[tum_robot] = path;
    return Status::Ok();
  }
  static const char* const kSuffixes[2] = {channels::kGroundTruthSuffix,
                                           channels::kReferenceSuffix};  // preference order
  std::map<std::string, StampedTrajectory> by_suffix[2];
  for (int k = 0; k < 2; ++k) {
    if (Status s = ReadPoseChannels(path, kSuffixes[k], &by_suffix[k], &references->undecodable);
        !s.ok()) {
      return s;
    }
  }
  for (int k = 1; k >= 0; --k) {  // ground truth overwrites reference
    for (auto& [robot, poses] : by_suffix[k]) {
      references->by_robot[robot] = std::move(poses);
      references->source_by_robot[robot] = robot + kSuffixes[k];
    }
  }
  if (references->by_robot.empty()) {
    return Status::Error(path + ": no <ROBOT>_GROUND_TRUTH or <ROBOT>_REFERENCE poses");
  }
  return Status::Ok();
}

}  // namespace anchormap
