#pragma once
// Default LCM channel names (upper case), in one place. Every daemon lets a flag override
// each of them; see docs/DAEMONS.md for the table of channels and message types.

#include <string>

namespace anchormap::channels {

// Robot inputs, per robot ("R1_ODOMETRY", ...).
inline std::string Odometry(const std::string& robot) { return robot + "_ODOMETRY"; }  // pose_t
inline std::string Laser(const std::string& robot) { return robot + "_LASER"; }  // planar_lidar_t
inline std::string Encounter(const std::string& robot) {  // encounter_t, observer = robot
  return robot + "_ENCOUNTER";
}
inline std::string GroundTruth(const std::string& robot) {  // pose_t, eval only
  return robot + "_GROUND_TRUTH";
}
inline std::string Reference(const std::string& robot) { return robot + "_REFERENCE"; }

// Agents -> server.
inline constexpr char kKeyframes[] = "ANCHORMAP_KEYFRAMES";    // keyframe_t
inline constexpr char kEncounters[] = "ANCHORMAP_ENCOUNTERS";  // encounter_t (trajectory filled)
// Server -> agents: delivery of keyframes and relayed encounters.
inline constexpr char kAcks[] = "ANCHORMAP_ACKS";                       // delivery_ack_t
inline constexpr char kResendRequests[] = "ANCHORMAP_RESEND_REQUESTS";  // resend_request_t
// Server -> users.
inline constexpr char kMergedMap[] = "ANCHORMAP_MERGED_MAP";  // merged_map_t
inline constexpr char kAnchorCovariances[] =
    "ANCHORMAP_ANCHOR_COVARIANCES";                                 // anchor_covariances_t
inline constexpr char kGridTiles[] = "ANCHORMAP_GRID_TILES";        // grid_tile_t
inline constexpr char kServerStatus[] = "ANCHORMAP_SERVER_STATUS";  // server_status_t

}  // namespace anchormap::channels
