#include "agent/node/agent_node.h"

#include <cstdio>

#include "common/bus/channels.h"
#include "common/bus/codec.h"
#include "common/bus/delivery_codec.h"

namespace anchormap {

AgentNodeOptions WithDefaultChannels(AgentNodeOptions options) {
  const std::string& robot = options.agent.robot;
  if (options.channels.odometry.empty()) options.channels.odometry = channels::Odometry(robot);
  if (options.channels.laser.empty()) options.channels.laser = channels::Laser(robot);
  if (options.channels.laser_mount.empty()) {
    options.channels.laser_mount = options.channels.laser + "_MOUNT";
  }
  if (options.channels.encounter.empty()) options.channels.encounter = channels::Encounter(robot);
  return options;
}

AgentNode::AgentNode(const AgentNodeOptions& options, Publish publish)
    : options_(WithDefaultChannels(options)),
      publish_(std::move(publish)),
      agent_(options_.agent),
      outbox_(options_.outbox) {}

std::vector<std::string> AgentNode::InputChannels() const {
  return {options_.channels.odometry,       options_.channels.laser,
          options_.channels.laser_mount,    options_.channels.encounter,
          options_.channels.encounters,     options_.channels.acks,
          options_.channels.resend_requests};
}

bool AgentNode::OnMessage(const std::string& channel, const uint8_t* data, size_t size) {
  // What comes from the fleet's bus (relays, the server's acks and resend requests) is
  // sealed when authentication is on; the robot's own sensor channels are local.
  const bool from_fleet = channel == options_.channels.encounters ||
                          channel == options_.channels.acks ||
                          channel == options_.channels.resend_requests;
  std::vector<uint8_t> opened;
  if (from_fleet && authenticator_) {
    Result<std::vector<uint8_t>> payload = authenticator_->Open(channel, data, size);
    if (!payload.ok()) {
      rejects_.Count(payload.status(), channel);  // forged fleet messages are ours to count
      return true;
    }
    opened = std::move(*payload);
    data = opened.data();
    size = opened.size();
  }
  AgentOutput out;
  Status refused;
  if (channel == options_.channels.odometry) {
    const Result<OdometrySample> odometry = DecodeOdometry(data, size);
    refused = odometry.ok() ? agent_.OnOdometry(*odometry, &out) : odometry.status();
  } else if (channel == options_.channels.laser) {
    Result<LaserScan> scan = DecodeLaser(data, size);
    refused = scan.ok() ? agent_.OnScan(std::move(*scan), &out) : scan.status();
  } else if (channel == options_.channels.laser_mount) {
    // A pose_t like odometry: the laser's pose in the body frame.
    const Result<OdometrySample> mount = DecodeOdometry(data, size);
    refused = mount.ok() ? agent_.SetSensorMounting(mount->T_odom_body) : mount.status();
  } else if (channel == options_.channels.encounter || channel == options_.channels.encounters) {
    const Result<Encounter> encounter = DecodeEncounter(data, size);
    if (channel == options_.channels.encounters) {
      // Others' bad relays on the shared channel are the server's to count.
      if (encounter.ok()) agent_.OnRelayedEncounter(*encounter);
      return true;
    }
    refused = encounter.ok() ? agent_.OnEncounter(*encounter, &out) : encounter.status();
  } else if (channel == options_.channels.acks || channel == options_.channels.resend_requests) {
    OnDelivery(channel, data, size);
    return true;
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
    Send(StreamKind::kKeyframes, keyframe.seq, EncodeKeyframe(keyframe), context);
  }
  for (const Encounter& encounter : out.encounters) {
    Send(StreamKind::kEncounters, encounter.seq, EncodeEncounter(encounter), context);
  }
}

void AgentNode::EnableAuthentication(Authenticator authenticator) {
  authenticator_.emplace(std::move(authenticator));
}

void AgentNode::PublishSealed(const std::string& channel, const std::vector<uint8_t>& bytes) {
  if (authenticator_) {
    publish_(channel, authenticator_->Seal(channel, bytes.data(), bytes.size()));
  } else {
    publish_(channel, bytes);
  }
}

void AgentNode::Send(StreamKind kind, int32_t seq, std::vector<uint8_t> bytes,
                     const std::string& context) {
  PublishSealed(
      kind == StreamKind::kKeyframes ? options_.channels.keyframes : options_.channels.encounters,
      bytes);
  if (!options_.reliable) return;
  if (Status kept = outbox_.Add(kind, seq, std::move(bytes), now_utime_); !kept.ok()) {
    rejects_.Count(kept, context);
  }
}

void AgentNode::Resend(const std::vector<Outbox::Message>& messages) {
  // Kept unsealed: each (re)send is sealed under a fresh counter, so a resend of a
  // message the server never saw is not a replay.
  for (const Outbox::Message& message : messages) {
    PublishSealed(message.kind == StreamKind::kKeyframes ? options_.channels.keyframes
                                                         : options_.channels.encounters,
                  message.bytes);
  }
}

void AgentNode::OnDelivery(const std::string& channel, const uint8_t* data, size_t size) {
  // Malformed or foreign acknowledgements are not this agent's to count: the trajectory
  // id and robot name select this session's.
  const auto mine = [this](const std::string& robot, int64_t trajectory_id) {
    return robot == options_.agent.robot && trajectory_id == options_.agent.trajectory_id;
  };
  if (channel == options_.channels.acks) {
    const Result<DeliveryAck> ack = DecodeDeliveryAck(data, size);
    if (ack.ok() && mine(ack->robot, ack->trajectory_id)) {
      outbox_.Acknowledge(ack->keyframes_next, ack->encounters_next);
      Resend(outbox_.EncountersLeftByAck(now_utime_));
    }
    return;
  }
  const Result<ResendRequest> request = DecodeResendRequest(data, size);
  if (request.ok() && mine(request->robot, request->trajectory_id)) {
    Resend(outbox_.Requested(request->ranges, now_utime_));
  }
}

void AgentNode::Poll(int64_t now_utime) {
  now_utime_ = now_utime;
  Resend(outbox_.TimedOut(now_utime));
}

std::string AgentNode::StatusLine() const {
  const AgentStats& s = agent_.stats();
  return options_.agent.robot + " trajectory " + std::to_string(options_.agent.trajectory_id) +
         ": odometry " + std::to_string(s.odometry_readings) + " scans " + std::to_string(s.scans) +
         " keyframes " + std::to_string(s.keyframes) + " (forced " +
         std::to_string(s.forced_keyframes) + ") encounters relayed " +
         std::to_string(s.encounters_relayed) + " waiting scans " +
         std::to_string(agent_.pending_scans()) + " outbox " + std::to_string(outbox_.size()) +
         " (" + std::to_string(outbox_.bytes()) + " bytes; spilled " +
         std::to_string(outbox_.spilled_entries()) + " (" +
         std::to_string(outbox_.stats().spilled) + " in all, " +
         std::to_string(outbox_.stats().read_back) + " read back), " +
         std::to_string(outbox_.spill_file_bytes()) + " bytes on disk) acknowledged " +
         std::to_string(outbox_.stats().acknowledged) + " resent " +
         std::to_string(outbox_.stats().resent_on_request) + "+" +
         std::to_string(outbox_.stats().resent_on_timeout) + " dropped " +
         std::to_string(outbox_.stats().dropped) + " " + ScanMatchingStatus() +
         " rejected: " + rejects_.Summary();
}

std::string AgentNode::ScanMatchingStatus() const {
  const ScanRefinementStats& r = agent_.refinement_stats();
  if (!options_.agent.scan_matching.enabled) return "scan matching off";
  char cpu[96];
  std::snprintf(cpu, sizeof(cpu), " cpu %.2f ms/scan (max %.1f)", 1e3 * r.mean_scan_cpu_s(),
                1e3 * r.max_scan_cpu_s);
  const AgentStats& s = agent_.stats();
  return "scan matching: matched " + std::to_string(r.matched) + "/" + std::to_string(r.scans) +
         " odometry " + std::to_string(r.fallbacks) + " map starts " +
         std::to_string(r.map_starts) + " flat " + std::to_string(r.flat) + cpu +
         " constraints matched " + std::to_string(s.matched_constraints) + " (flat " +
         std::to_string(s.flat_constraints) + ") odometry " +
         std::to_string(s.odometry_constraints);
}

}  // namespace anchormap
