#pragma once
// The agent between bytes and logic: decodes odometry, laser and encounter messages with
// the codec (refusals counted per channel, logged once per kind), feeds Agent, and encodes
// the keyframes and relayed encounters for a publish callback (LCM in agent_main.cc, a
// memq:// bus in tests). No LCM header here: bytes only.

#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "agent/agent.h"
#include "agent/node/agent_node_options.h"
#include "agent/outbox.h"
#include "common/bus/authenticator.h"
#include "common/util/reject_counter.h"

namespace anchormap {

class AgentNode {
 public:
  using Publish =
      std::function<void(const std::string& channel, const std::vector<uint8_t>& bytes)>;

  // `options` must be valid with a trajectory id chosen; empty input channels are
  // derived from the robot name.
  AgentNode(const AgentNodeOptions& options, Publish publish);

  // The channels to subscribe to: odometry, laser, the robot's encounter channel, the
  // server's encounter channel (to force a keyframe when this robot is observed), and the
  // server's acknowledgements and resend requests.
  std::vector<std::string> InputChannels() const;
  // From now on keyframes and relays go out sealed under `authenticator`'s signing key, and
  // what comes from the fleet's bus (relays, acknowledgements, resend requests) must be
  // sealed under one of its keys (the robot's own sensor channels are local, unsigned).
  void EnableAuthentication(Authenticator authenticator);
  // One message; returns false for a channel that is not an input. Every keyframe and
  // relayed encounter published is kept in the outbox until acknowledged; a resend
  // request for this trajectory publishes the kept ones again.
  bool OnMessage(const std::string& channel, const uint8_t* data, size_t size);
  // The clock of the outbox (wall time online; tests and anchormap-replay leave it at 0).
  void SetClock(int64_t now_utime) { now_utime_ = now_utime; }
  // Resends what has waited too long for an acknowledgement (call on a timer).
  void Poll(int64_t now_utime);
  // "R1 trajectory 17...: odometry 5000 scans 1000 keyframes 120 relayed 3 ... scan matching:
  // matched 990/1000 ... cpu 1.20 ms/scan (max 4.0) ... rejected: none"
  std::string StatusLine() const;

  const Agent& agent() const { return agent_; }
  const RejectCounter& rejects() const { return rejects_; }
  const Outbox& outbox() const { return outbox_; }
  const AgentNodeOptions& options() const { return options_; }

 private:
  void Emit(const AgentOutput& out, const std::string& context);
  // Scans matched and fallen back to odometry, CPU per scan (thread clock), constraints.
  std::string ScanMatchingStatus() const;
  void Send(StreamKind kind, int32_t seq, std::vector<uint8_t> bytes, const std::string& context);
  void Resend(const std::vector<Outbox::Message>& messages);
  // Acknowledgements and resend requests (for this trajectory only).
  void OnDelivery(const std::string& channel, const uint8_t* data, size_t size);

  AgentNodeOptions options_;
  Publish publish_;
  // Publishes `bytes`, sealed when authentication is on.
  void PublishSealed(const std::string& channel, const std::vector<uint8_t>& bytes);

  Agent agent_;
  Outbox outbox_;
  RejectCounter rejects_;
  int64_t now_utime_ = 0;
  std::optional<Authenticator> authenticator_;
};

}  // namespace anchormap
