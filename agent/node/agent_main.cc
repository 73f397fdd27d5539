// anchormap-agent: runs on each robot. Subscribes to the robot's odometry and laser (and
// its encounter channel), publishes keyframes and relays encounters to the server.

#include <chrono>
#include <iostream>
#include <sstream>

#include "agent/node/agent_node.h"
#include "agent/node/agent_node_options.h"
#include "agent/spill_file.h"
#include "agent/trajectory_id.h"
#include "common/bus/authenticator.h"
#include "common/bus/lcm_loop.h"
#include "common/util/log.h"
#include "common/util/options_loader.h"

namespace anchormap {
namespace {

int64_t WallUtime() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

void Register(OptionsLoader* l, AgentNodeOptions* node) {
  AgentOptions* o = &node->agent;
  l->Add("robot", "robot", &o->robot, "robot name, upper case (e.g. R1)", /*required=*/true);
  l->Add("trajectory_id", "trajectory-id", &o->trajectory_id,
         "this session's trajectory id (0: 63 random bits from the OS, a new one per run; a "
         "reused id after a restart still gives a new trajectory on the server)");
  AddLcmUrlOption(l, &node->lcm_url);
  l->Add("max_range_m", "max-range-m", &o->max_range_m,
         "ranges at or beyond this are no-returns (planar_lidar_t carries no max range), m");
  l->Add("sensor.x_m", "sensor-x-m", &o->sensor_x_m,
         "laser position on the robot, forward (m; a message on the laser mount channel "
         "replaces the sensor.* values)");
  l->Add("sensor.y_m", "sensor-y-m", &o->sensor_y_m, "laser position on the robot, left (m)");
  l->Add("sensor.theta_rad", "sensor-theta-rad", &o->sensor_theta_rad,
         "laser heading on the robot (rad)");
  l->Add("keyframer.max_distance_m", "keyframe-distance-m", &o->keyframer.max_distance_m,
         "new keyframe after this much travel (m)");
  l->Add("keyframer.max_angle_rad", "keyframe-angle-rad", &o->keyframer.max_angle_rad,
         "new keyframe after this much rotation (rad)");
  l->Add("keyframer.max_interval_s", "keyframe-interval-s", &o->keyframer.max_interval_s,
         "new keyframe after this long without one (s; 0 = off)");
  l->Add("noise.xy_base_m", "noise-xy-base-m", &o->noise.xy_base_m,
         "odometry sigma_xy = base + per_m * distance (m)");
  l->Add("noise.xy_per_m", "noise-xy-per-m", &o->noise.xy_per_m,
         "odometry sigma_xy growth per metre");
  l->Add("noise.theta_base_rad", "noise-theta-base-rad", &o->noise.theta_base_rad,
         "odometry sigma_theta = base + per_rad * |angle| + per_m * distance (rad)");
  l->Add("noise.theta_per_rad", "noise-theta-per-rad", &o->noise.theta_per_rad,
         "sigma_theta growth per radian turned");
  l->Add("noise.theta_per_m", "noise-theta-per-m", &o->noise.theta_per_m,
         "sigma_theta growth per metre (rad/m)");
  l->Add("odometry.capacity", "odometry-capacity", &o->odometry.capacity, "odometry readings kept");
  l->Add("odometry.max_gap_s", "odometry-max-gap-s", &o->odometry.max_gap_s,
         "no interpolation across a longer odometry gap (s)");
  l->Add("scan_matching.enabled", "scan-matching", &o->scan_matching.enabled,
         "refine odometry by matching each scan against a local map of the last ones "
         "(false: keyframes carry raw odometry)");
  l->Add("scan_matching.min_points", "scan-matching-min-points", &o->scan_matching.min_points,
         "scans with fewer returns are not matched (odometry for them)");
  l->Add("scan_matching.local_map.held_back_min_odometry_m", "scan-matching-held-back-m",
         &o->scan_matching.local_map.held_back_min_odometry_m,
         "a match is refused as held back when odometry drove at least this far since the local "
         "map's newest scan while the match moved less than half as far (m; a corridor slide)");
  l->Add("max_pending_scans", "max-pending-scans", &o->max_pending_scans,
         "scans waiting for odometry to reach their time");
  l->Add("status_period_s", "status-period-s", &node->status_period_s,
         "status line period (s; 0 = off)");
  l->Add("log_level", "log-level", &node->log_level, "debug, info, warning or error");
  l->Add("key_file", "key-file", &node->key_file,
         "sign keyframes and relays with a key of this file and check others' relays "
         "(empty: no authentication, with a warning)");
  l->Add("key_id", "key-id", &node->key_id, "the signing key's id (empty: the file's first)");
  l->Add("channels.odometry", "odometry-channel", &node->channels.odometry,
         "pose_t input (empty: <ROBOT>_ODOMETRY)");
  l->Add("channels.laser", "laser-channel", &node->channels.laser,
         "planar_lidar_t input (empty: <ROBOT>_LASER)");
  l->Add("channels.laser_mount", "laser-mount-channel", &node->channels.laser_mount,
         "pose_t input: the laser's pose on the robot, e.g. from anchormap-import-carmen "
         "(empty: <laser channel>_MOUNT)");
  l->Add("channels.encounter", "encounter-channel", &node->channels.encounter,
         "encounter_t input from the robot's detector (empty: <ROBOT>_ENCOUNTER)");
  l->Add("channels.keyframes", "keyframes-channel", &node->channels.keyframes, "keyframe_t output");
  l->Add("channels.encounters", "encounters-channel", &node->channels.encounters,
         "encounter_t output (relays; also read, to see this robot being observed)");
  l->Add("channels.acks", "acks-channel", &node->channels.acks,
         "delivery_ack_t input (the server's acknowledgements)");
  l->Add("channels.resend_requests", "resend-requests-channel", &node->channels.resend_requests,
         "resend_request_t input (the server asks for missing keyframes / encounters)");
  l->Add("outbox.max_bytes", "outbox-max-bytes", &node->outbox.max_bytes,
         "bytes of unacknowledged keyframes / encounters kept in memory for resending; past "
         "it the oldest spill to --outbox-spill-dir");
  l->Add("outbox.spill_dir", "outbox-spill-dir", &node->outbox.spill_dir,
         "past --outbox-max-bytes the oldest unacknowledged messages go to a scratch file in "
         "this folder (unlinked at once: nothing is left behind) and are read back for resends "
         "(empty: no spilling, the oldest are dropped)");
  l->Add("outbox.max_spill_bytes", "outbox-max-spill-bytes", &node->outbox.max_spill_bytes,
         "bytes the spill file may hold; past it the oldest are dropped and counted (queue_full)");
  l->Add("exit_ack_wait_s", "exit-ack-wait-s", &node->exit_ack_wait_s,
         "on SIGINT / SIGTERM, wait up to this long for the server to acknowledge what was "
         "published, then exit saying what was left unacknowledged (s; 0: exit at once; a "
         "second signal ends the wait)");
  l->Add("outbox.resend_timeout_s", "resend-timeout-s", &node->outbox.resend_timeout_s,
         "resend an unacknowledged message after this long (s; then 2x, then 4x)");
  l->Add("outbox.encounter_resend_after_ack_s", "encounter-resend-after-ack-s",
         &node->outbox.encounter_resend_after_ack_s,
         "an acknowledgement that leaves out an encounter sent this long ago has it resent at "
         "once (s; 0: off)");
}

// On SIGINT / SIGTERM (Run has returned) what the server has not acknowledged yet is not
// dropped at once: the loop runs on (acknowledgements, resend requests, timeout resends)
// until the outbox is empty, for at most `wait_s`; a second signal ends the wait.
void WaitForAcknowledgements(double wait_s, LcmLoop* loop, const AgentNode& node) {
  const Outbox& outbox = node.outbox();
  if (outbox.size() == 0) {
    LogInfo("everything published was acknowledged by the server");
    return;
  }
  if (wait_s > 0) {
    std::ostringstream line;
    line << "waiting up to " << wait_s << " s for the server to acknowledge " << outbox.size()
         << " messages (" << outbox.Unacknowledged() << "; a second signal ends the wait)";
    LogInfo(line.str());
    loop->StopOnSignals(
        [](int number) { LogWarning("signal " + std::to_string(number) + ": not waiting"); });
    const auto start = std::chrono::steady_clock::now();
    const bool all = loop->RunUntil([&outbox] { return outbox.size() == 0; },
                                    std::chrono::milliseconds(static_cast<int64_t>(1e3 * wait_s)));
    if (all) {
      line.str("");
      line << "everything published was acknowledged by the server after "
           << std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()
           << " s";
      LogInfo(line.str());
      return;
    }
  }
  LogWarning("exiting with " + std::to_string(outbox.size()) +
             " messages the server has not acknowledged: " + outbox.Unacknowledged());
}

int Main(int argc, char** argv) {
  AgentNodeOptions options;
  OptionsLoader loader("anchormap-agent", "--robot R1 [--lcm-url URL] [--config FILE] [options]",
                       "The anchormap agent (one per robot): turns odometry and laser scans into\n"
                       "keyframes for anchormap-server and relays the robot's direct encounters.");
  Register(&loader, &options);
  const ParseOutcome outcome = loader.Parse(argc, argv);
  if (!outcome.run) return outcome.exit_code;
  if (Status valid = options.Validate(); !valid.ok()) return loader.UsageError(valid);
  if (options.agent.trajectory_id == 0) options.agent.trajectory_id = DrawTrajectoryId();
  options = WithDefaultChannels(options);
  if (Status logging =
          loader.StartLogging(options.log_level, "anchormap-agent " + options.agent.robot,
                              "effective configuration (trajectory id " +
                                  std::to_string(options.agent.trajectory_id) + ")");
      !logging.ok()) {
    return loader.UsageError(logging);
  }

  Result<std::unique_ptr<LcmLoop>> created = LcmLoop::Create(options.lcm_url);
  if (!created.ok()) {
    LogError(created.status().message());
    return 1;
  }
  std::unique_ptr<LcmLoop> loop = std::move(*created);
  LcmLoop* bus = loop.get();
  if (!options.outbox.spill_dir.empty()) {
    // A folder that cannot take the spill file is said now, not when the server has been
    // away long enough to need it.
    if (Result<std::unique_ptr<SpillFile>> probe = SpillFile::Create(options.outbox.spill_dir);
        !probe.ok()) {
      LogWarning(probe.status().message() + ": the outbox will not spill (past " +
                 std::to_string(options.outbox.max_bytes) +
                 " bytes unacknowledged, the oldest are dropped)");
      options.outbox.spill_dir.clear();
    }
  }
  AgentNode node(options, [bus](const std::string& channel, const std::vector<uint8_t>& bytes) {
    const Status status = bus->Publish(channel, bytes);
    if (!status.ok()) LogWarning(status.message());
  });
  if (options.key_file.empty()) {
    LogWarning("no --key-file: keyframes and encounters go out unauthenticated");
  } else {
    AuthenticatorOptions auth;
    auth.signing_key_id = options.key_id;
    auth.sender = options.agent.robot;
    auth.first_counter = std::chrono::duration_cast<std::chrono::microseconds>(
                             std::chrono::system_clock::now().time_since_epoch())
                             .count();
    Result<Authenticator> authenticator = LoadAuthenticator(options.key_file, auth);
    if (!authenticator.ok()) {
      LogError(authenticator.status().message());
      return 1;
    }
    LogInfo("authentication on: signing with '" + authenticator->signing_key_id() + "' from " +
            options.key_file);
    node.EnableAuthentication(std::move(*authenticator));
  }
  bool stopping = false;
  for (const std::string& channel : node.InputChannels()) {
    const Status status = loop->Subscribe(
        channel,
        [&node, &stopping](const std::string& c, const uint8_t* data, size_t size) {
          // Stopping: no new keyframes, only the server's acknowledgements and requests.
          const AgentChannels& channels = node.options().channels;
          if (stopping && c != channels.acks && c != channels.resend_requests) return;
          node.SetClock(WallUtime());
          node.OnMessage(c, data, size);
        },
        1000);
    if (!status.ok()) {
      LogError(status.message());
      return 1;
    }
  }
  // Unacknowledged keyframes and encounters go out again after the resend timeout.
  loop->Every(std::chrono::milliseconds(100), [&node] { node.Poll(WallUtime()); });
  if (options.status_period_s > 0) {
    loop->Every(std::chrono::milliseconds(static_cast<int64_t>(1e3 * options.status_period_s)),
                [&node] { LogInfo(node.StatusLine()); });
  }
  loop->StopOnSignals(
      [](int number) { LogInfo("signal " + std::to_string(number) + ": stopping"); });
  LogInfo("listening on " + options.channels.odometry + ", " + options.channels.laser + ", " +
          options.channels.encounter);
  loop->Run();
  stopping = true;
  WaitForAcknowledgements(options.exit_ack_wait_s, loop.get(), node);
  // Kernel drops: sensor messages lost before the agent read them (its socket's receive
  // buffer was full), as the server reports its own.
  bus->RefreshKernelDrops();
  LogInfo("final: " + node.StatusLine() + " | lcm max burst " +
          std::to_string(bus->stats().max_burst) + " kernel drops " +
          std::to_string(bus->stats().kernel_drops));
  return 0;
}

}  // namespace
}  // namespace anchormap

int main(int argc, char** argv) { return anchormap::Main(argc, argv); }
