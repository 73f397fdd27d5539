#pragma once
// Options of anchormap-agent's bus side: the logic's options (AgentOptions) plus channels,
// the LCM URL, the status period and the log level. One source of defaults: --help, the
// config keys and docs/DAEMONS.md come from the registration in agent_main.cc.

#include <string>

#include "agent/agent_options.h"
#include "agent/outbox.h"
#include "common/bus/channels.h"
#include "common/util/status.h"

namespace anchormap {

struct AgentChannels {
  // Empty: derived from the robot name (R1_ODOMETRY, R1_LASER, R1_ENCOUNTER).
  std::string odometry;
  std::string laser;
  // The laser's mounting pose (pose_t, e.g. from anchormap-import-carmen); empty: the laser
  // channel + "_MOUNT" (R1_LASER_MOUNT).
  std::string laser_mount;
  std::string encounter;
  std::string keyframes = channels::kKeyframes;
  std::string encounters = channels::kEncounters;
  std::string acks = channels::kAcks;                       // delivery_ack_t input
  std::string resend_requests = channels::kResendRequests;  // resend_request_t input
};

// The daemon's outbox spills past its memory bound to /var/tmp (on disk on Debian, where
// /tmp may be a tmpfs in memory): a server away for long must not cost keyframes.
inline OutboxOptions SpillingOutboxOptions() {
  OutboxOptions options;
  options.spill_dir = "/var/tmp";
  return options;
}

struct AgentNodeOptions {
  AgentOptions agent;
  AgentChannels channels;
  OutboxOptions outbox = SpillingOutboxOptions();
  // On SIGINT / SIGTERM the agent waits up to this long for the server to acknowledge
  // what it published before it exits (0: exits at once).
  double exit_ack_wait_s = 10.0;
  // Keep what is published for resending until acknowledged (off where the bus loses
  // nothing and no server acknowledges: anchormap-replay over memq://).
  bool reliable = true;
  std::string lcm_url;           // empty: LCM's default ($LCM_DEFAULT_URL or udpm default)
  double status_period_s = 5.0;  // status line period (0 = off)
  std::string log_level = "info";
  // Authentication (common/bus/authenticator.h; empty: none, with a warning at start).
  std::string key_file;
  std::string key_id;  // the key that signs this agent's messages (empty: the file's first)

  Status Validate() const {
    if (status_period_s < 0) return Status::Error("status_period_s must be >= 0");
    if (!(exit_ack_wait_s >= 0)) return Status::Error("exit_ack_wait_s must be >= 0");
    if (Status e = outbox.Validate(); !e.ok()) return e;
    if (!key_id.empty() && key_file.empty()) return Status::Error("--key-id needs --key-file");
    return agent.Validate();
  }
};

// The options with empty channel names filled from the robot name.
AgentNodeOptions WithDefaultChannels(AgentNodeOptions options);

}  // namespace anchormap
