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

  // The channels to subscribe to: odometry, laser, the robot's encounter channel, and
  // the server's encounter channel (to force a keyframe when this robot is observed).
  std::vector<std::string> InputChannels() const;
  // From now on keyframes and relays go out sealed under `authenticator`'s signing key, and
  // relays read back from the shared encounter channel must be sealed under one of its
  // keys (the robot's own sensor channels are local and stay unsigned).
  void EnableAuthentication(Authenticator authenticator);
  // One message; returns false for a channel that is not an input.
  bool OnMessage(const std::string& channel, const uint8_t* data, size_t size);
  // "R1 trajectory 17...: odometry 5000 scans 1000 keyframes 120 relayed 3 rejected: none"
  std::string StatusLine() const;

  const Agent& agent() const { return agent_; }
  const RejectCounter& rejects() const { return rejects_; }
  const AgentNodeOptions& options() const { return options_; }

 private:
  void Emit(const AgentOutput& out, const std::string& context);

  AgentNodeOptions options_;
  Publish publish_;
  void Send(const std::string& channel, const std::vector<uint8_t>& bytes);

  Agent agent_;
  RejectCounter rejects_;
  std::optional<Authenticator> authenticator_;
};

}  // namespace anchormap
