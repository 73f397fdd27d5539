#include "agent/agent_node.h"

#include "common/bus/channels.h"
#include "common/bus/codec.h"

namespace anchormap {

AgentOptions WithDefaultChannels(AgentOptions options) {
  if (options.channels.odometry.empty())
    options.channels.odometry = channels::Odometry(options.robot);
  if (options.channels.laser.empty()) options.channels.laser = channels::Laser(options.robot);
  if (options.channels.encounter.empty()) {
    options.channels.encounter = channels::Encounter(options.robot);
  }
  return options;
}

AgentNode::AgentNode(const AgentOptions& options, Publish publish)
    : options_(WithDefaultChannels(options)), publish_(std::move(publish)), agent_(options_) {}

std::vector<std::string> AgentNode::InputChannels() const {
  return {options_.channels.odometry, options_.channels.laser, options_.channels.encounter,
          options_.channels.encounters};
}

bool AgentNode::OnMessage(const std::string& channel, const uint8_t* data, size_t size) {
  AgentOutput out;
  std::optional<ErrorCode> refused;
  std::string detail;
  if (channel == options_.channels.odometry) {
    const Decoded<OdometrySample> odometry = DecodeOdometry(data, size);
    if (!odometry.ok()) {
      rejects_.Count(odometry.reason, channel, odometry.detail);
      return true;
    }
    refused = agent_.OnOdometry(*odometry.value, &out);
    detail = "odometry at " + std::to_string(odometry.value->utime);
  } else if (channel == options_.channels.laser) {
    const Decoded<LaserScan> scan =
        DecodeLaser(data, size, static_cast<float>(options_.max_range_m),
                    Pose2(options_.sensor_x_m, options_.sensor_y_m, options_.sensor_theta_rad));
    if (!scan.ok()) {
      rejects_.Count(scan.reason, channel, scan.detail);
      return true;
    }
    refused = agent_.OnScan(*scan.value, &out);
    detail = "scan at " + std::to_string(scan.value->utime);
  } else if (channel == options_.channels.encounter || channel == options_.channels.encounters) {
    const Decoded<Encounter> encounter = DecodeEncounter(data, size);
    if (!encounter.ok()) {
      // Others' bad relays on the shared channel are the server's to count.
      if (channel == options_.channels.encounter)
        rejects_.Count(encounter.reason, channel, encounter.detail);
      return true;
    }
    if (channel == options_.channels.encounters) {
      agent_.OnRelayedEncounter(*encounter.value);
      return true;
    }
    refused = agent_.OnEncounter(*encounter.value, &out);
    detail = "encounter " + encounter.value->observer + "->" + encounter.value->observed;
  } else {
    return false;
  }
  if (refused) rejects_.Count(*refused, channel, detail);
  Emit(out, channel);
  return true;
}

void AgentNode::Emit(const AgentOutput& out, const std::string& context) {
  for (ErrorCode reason : out.late_rejections) {
    rejects_.Count(reason, context, "a scan waiting for odometry was dropped");
  }
  for (const Keyframe& keyframe : out.keyframes) {
    publish_(options_.channels.keyframes, EncodeKeyframe(keyframe));
  }
  for (const Encounter& encounter : out.encounters) {
    publish_(options_.channels.encounters, EncodeEncounter(encounter));
  }
}

std::string AgentNode::StatusLine() const {
  const AgentStats& s = agent_.stats();
  return options_.robot + " trajectory " + std::to_string(options_.trajectory_id) + ": odometry " +
         std::to_string(s.odometry_readings) + " scans " + std::to_string(s.scans) + " keyframes " +
         std::to_string(s.keyframes) + " (forced " + std::to_string(s.forced_keyframes) +
         ") encounters relayed " + std::to_string(s.encounters_relayed) + " waiting scans " +
         std::to_string(agent_.pending_scans()) + " rejected: " + rejects_.Summary();
}

}  // namespace anchormap
