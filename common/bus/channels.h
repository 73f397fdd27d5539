#pragma once
// Default LCM channel names (upper case), in one place. Every daemon lets a flag override
// each of them; see docs/DAEMONS.md for the table of channels and message types.

#include <string>

namespace anchormap::channels {

// Robot inputs, per robot: the robot's name and a suffix ("R1_ODOMETRY", ...).
inline constexpr char kOdometrySuffix[] = "_ODOMETRY";         // pose_t
inline constexpr char kLaserSuffix[] = "_LASER";               // planar_lidar_t
inline constexpr char kEncounterSuffix[] = "_ENCOUNTER";       // encounter_t, observer = robot
inline constexpr char kGroundTruthSuffix[] = "_GROUND_TRUTH";  // pose_t, simulator, eval only
inline constexpr char kReferenceSuffix[] = "_REFERENCE";       // pose_t, importer, eval only
// The laser's mounting pose in the robot body frame (pose_t: pos x y, yaw), from the log the
// importer read; the agent applies it to the scans (overriding its --sensor-* flags).
inline constexpr char kLaserMountSuffix[] = "_LASER_MOUNT";
// The importer's --simultaneous time shift of this robot's piece (pose_t, identity pose): its
// utime field is the shift in microseconds added to the log's times (log time = message time -
// shift), so that anchormap-eval maps times back to the relations' clock. Eval only.
inline constexpr char kClockShiftSuffix[] = "_CLOCK_SHIFT";
// anchormap-import-carmen, one bot_core.pose_t per scan whose stamp in the log stepped back and
// was repaired: utime is the scan's time in the log written, pos[0] the log's stamp minus the
// repaired time in microseconds, so that anchormap-eval finds the relations' scans. Eval only.
inline constexpr char kTimeRepairSuffix[] = "_TIME_REPAIR";
inline std::string Odometry(const std::string& robot) { return robot + kOdometrySuffix; }
inline std::string Laser(const std::string& robot) { return robot + kLaserSuffix; }
inline std::string Encounter(const std::string& robot) { return robot + kEncounterSuffix; }
inline std::string GroundTruth(const std::string& robot) { return robot + kGroundTruthSuffix; }
inline std::string Reference(const std::string& robot) { return robot + kReferenceSuffix; }
inline std::string LaserMount(const std::string& robot) { return robot + kLaserMountSuffix; }
inline std::string ClockShift(const std::string& robot) { return robot + kClockShiftSuffix; }
inline std::string TimeRepair(const std::string& robot) { return robot + kTimeRepairSuffix; }

// Agents -> server.
inline constexpr char kKeyframes[] = "ANCHORMAP_KEYFRAMES";    // keyframe_t
inline constexpr char kEncounters[] = "ANCHORMAP_ENCOUNTERS";  // encounter_t (trajectory filled)
// Server -> agents: delivery of keyframes and relayed encounters.
inline constexpr char kAcks[] = "ANCHORMAP_ACKS";                       // delivery_ack_t
inline constexpr char kResendRequests[] = "ANCHORMAP_RESEND_REQUESTS";  // resend_request_t
// Server -> users.
// The merged map: its header (merged_map_header_t) after the chunks that changed
// (merged_map_chunk_t); MergedMapAssembler puts them together.
inline constexpr char kMapHeader[] = "ANCHORMAP_MAP_HEADER";  // merged_map_header_t
inline constexpr char kMapChunks[] = "ANCHORMAP_MAP_CHUNKS";  // merged_map_chunk_t
// The merged map as one message, which servers before the chunks published (read from
// their logs).
inline constexpr char kMergedMap[] = "ANCHORMAP_MERGED_MAP";  // merged_map_t
inline constexpr char kAnchorCovariances[] =
    "ANCHORMAP_ANCHOR_COVARIANCES";                                 // anchor_covariances_t
inline constexpr char kGridTiles[] = "ANCHORMAP_GRID_TILES";        // grid_tile_t
inline constexpr char kServerStatus[] = "ANCHORMAP_SERVER_STATUS";  // server_status_t

}  // namespace anchormap::channels
