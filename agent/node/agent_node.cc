#include "agent/node/agent_node.h"

#include "common/bus/channels.h"
#include "common/bus/codec.h"

namespace anchormap {

AgentNodeOptions WithDefaultChannels(AgentNodeOptions options) {
  const std::string& robot = options.agent.robot;
  if (options.channels.odometry.empty()) options.channels.odometry = channels::Odometry(robot);
  if (options.channels.laser.empty()) options.channels.laser = channels::Laser(robot);
  if (options.channels.encounter.empty()) options.channels.encounter = channels::Encounter(robot);
  return options;
}

AgentNode::AgentNode(const AgentNodeOptions& options, Publish publish)
    : options_(WithDefaultChannels(options)),
      publish_(std::move(publish)),
      agent_(options_.agent) {}

std::vector<std::string> AgentNode::InputChannels() const {
  return {options_.channels.odometry, options_.channels.laser, options_.channels.encounter,
          options_.channels.encounters};
}

bool AgentNode::OnMessage(const std::string& channel, const uint8_t* data, size_t size) {
  AgentOutput out;
  Status refused;
  if (channel == options_.channels.odometry) {
    const Result<OdometrySample> odometry = DecodeOdometry(data, size);
    refused = odometry.ok() ? agent_.OnOdometry(*odometry, &out) : odometry.status();
  } else if (channel == options_.channels.laser) {
    Result<LaserScan> scan = DecodeLaser(data, size);
    refused = scan.ok() ? agent_.OnScan(std::move(*scan), &out) : scan.status();
  } else if (channel == options_.channels.encounter || channel == options_.channels.encounters) {
    std::vector<uint8_t> opened;
    if (channel == options_.channels.encounters && authenticator_) {
      Result<std::vector<uint8_t>> payload = authenticator_->Open(channel, data, size);
      if (!payload.ok()) {
        rejects_.Count(payload.status(), channel);  // forged relays are ours to count
        return true;
      }
      opened = std::move(*payload);
      data = opened.data();
      size = opened.size();
    }
    const Result<Encounter> encounter = DecodeEncounter(data, size);
    if (channel == options_.channels.encounters) {
      // Others' bad relays on the shared channel are the server's to count.
      if (encounter.ok()) agent_.OnRelayedEncounter(*encounter);
      return true;
    }
    refused = encounter.ok() ? agent_.OnEncounter(*encounter, &out) : encounter.status();
  } else {
    return false;
  }
  if (!refused.ok()) rejects_.Count(refused, channel);
  Emit(out, channel);
  return true;
}

void AgentNode::Emit(const AgentOutput& out, const std::string& context) {
  for (const Status& refused : out.late_rejections) rejects_.Count(refused, context);
  for (const Keyframe& keyframe : out.keyframes) {
    Send(options_.channels.keyframes, EncodeKeyframe(keyframe));
  }
  for (const Encounter& encounter : out.encounters) {
    Send(options_.channels.encounters, EncodeEncounter(encounter));
  }
}

void AgentNode::EnableAuthentication(Authenticator authenticator) {
  authenticator_.emplace(std::move(authenticator));
}

void AgentNode::Send(const std::string& channel, const std::vector<uint8_t>& bytes) {
  if (authenticator_) {
    publish_(channel, authenticator_->Seal(channel, bytes.data(), bytes.size()));
  } else {
    publish_(channel, bytes);
  }
}

std::string AgentNode::StatusLine() const {
  const AgentStats& s = agent_.stats();
  return options_.agent.robot + " trajectory " + std::to_string(options_.agent.trajectory_id) +
         ": odometry " + std::to_string(s.odometry_readings) + " scans " + std::to_string(s.scans) +
         " keyframes " + std::to_string(s.keyframes) + " (forced " +
         std::to_string(s.forced_keyframes) + ") encounters relayed " +
         std::to_string(s.encounters_relayed) + " waiting scans " +
         std::to_string(agent_.pending_scans()) + " rejected: " + rejects_.Summary();
}

}  // namespace anchormap
