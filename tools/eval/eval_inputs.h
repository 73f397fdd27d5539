#pragma once
// The inputs of anchormap-eval. The estimate: the LAST complete merged map of a server
// output log (keyframe times and global poses per trajectory), or a TUM trajectory file (one
// trajectory). The references: every <ROBOT>_GROUND_TRUTH (simulator) or <ROBOT>_REFERENCE
// (CARMEN importer) channel of a raw log, or a TUM trajectory file (one robot).
// Undecodable messages and non-finite poses are counted and skipped, never fatal.

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "anchormap/merged_map_t.hpp"
#include "common/bus/authenticator.h"
#include "common/bus/channels.h"
#include "common/types/stamped_pose2.h"
#include "common/util/status.h"

namespace anchormap {

struct EstimatedTrajectory {
  std::string robot;
  int64_t trajectory_id = 0;
  bool anchored = false;
  // Anchored trajectories joined (directly or not) by the map's encounter links share a
  // group, numbered from 0 by decreasing number of poses; -1 for an unanchored trajectory.
  // When the map lists no encounter links at all, all anchored trajectories form group 0.
  int group = -1;
  StampedTrajectory poses;  // sorted by time; global frame when anchored, else local
};

struct MapEstimate {
  int64_t update = -1;  // the merged map's update number (-1 for a TUM file)
  int64_t utime = 0;
  int64_t maps_seen = 0;        // merged-map messages in the log (the last one is used)
  int64_t undecodable = 0;      // messages on the map channel that did not decode
  int64_t unauthenticated = 0;  // with a key: messages whose envelope was refused
  int64_t invalid_poses = 0;    // non-finite poses skipped
  int num_groups = 0;
  std::vector<EstimatedTrajectory> trajectories;
};

// True when the file starts with the LCM log sync word 0xEDA1DA01.
bool IsLcmLogFile(const std::string& path);

// Fills `estimate` from one merged map message (validating it; see MapEstimate).
void ConvertMergedMap(const merged_map_t& map, MapEstimate* estimate);

// Reads the estimate from an LCM log (the last complete merged map: MergedMapAssembler on
// `header_channel` + `chunks_channel`, or a merged_map_t on `channel` in logs of servers
// before the chunks) or, when `path` is not an LCM log, from a TUM trajectory file as robot
// `tum_robot`. Fails when the log holds no complete merged map. With `authenticator` (the
// server's --key-file) only messages in a valid envelope count (anchormap-server signs its
// outputs); the others are counted.
Status ReadMapEstimate(const std::string& path, const std::string& channel,
                       const std::string& tum_robot, MapEstimate* estimate,
                       Authenticator* authenticator = nullptr,
                       const std::string& header_channel = channels::kMapHeader,
                       const std::string& chunks_channel = channels::kMapChunks);

struct ReferenceSet {
  std::map<std::string, StampedTrajectory> by_robot;   // sorted by time
  std::map<std::string, std::string> source_by_robot;  // the channel (or file) used
  int64_t undecodable = 0;
};

// Every channel <ROBOT><suffix> of an LCM log decoded as bot_core.pose_t, per robot, sorted by
// time; messages that do not decode or carry non-finite poses are counted in *undecodable.
Status ReadPoseChannels(const std::string& path, const std::string& suffix,
                        std::map<std::string, StampedTrajectory>* by_robot, int64_t* undecodable);

// Reads references from an LCM log (<ROBOT>_GROUND_TRUTH preferred over <ROBOT>_REFERENCE
// when a log has both) or from a TUM file as robot `tum_robot`. Fails when nothing is found.
Status ReadReferences(const std::string& path, const std::string& tum_robot,
                      ReferenceSet* references);

}  // namespace anchormap
