#include "tests/fuzz/fuzz_samples.h"

#include <algorithm>

#include "common/bus/codec.h"
#include "common/bus/map_codec.h"
#include "server/map_chunker.h"

namespace anchormap::fuzz {
namespace {

constexpr int64_t kEpoch = 1'700'000'000'000'000;

LaserScan MakeScan(int n, int64_t utime) {
  LaserScan scan;
  scan.utime = utime;
  scan.rad0 = -1.5f;
  scan.radstep = 3.0f / static_cast<float>(n - 1);
  scan.max_range = 20.0f;
  for (int i = 0; i < n; ++i) scan.ranges.push_back(2.0f + 0.05f * static_cast<float>(i % 20));
  return scan;
}

Keyframe MakeKeyframe(const std::string& robot, int64_t trajectory, int32_t seq) {
  Keyframe k;
  k.robot = robot;
  k.trajectory_id = trajectory;
  k.seq = seq;
  k.encounters_relayed = seq / 2;  // an encounter relayed every other keyframe
  k.utime = kEpoch + 500'000 * seq;
  k.T_local_pose = Pose2(0.5 * seq, 0.1 * seq, 0.05 * seq);
  if (seq > 0) {
    k.T_previous_this = Pose2(0.5, 0.1, 0.05);
    k.T_previous_this_covariance = Eigen::Vector3d(0.01, 0.01, 0.001).asDiagonal();
  }
  k.scan = MakeScan(61, k.utime);
  return k;
}

std::vector<uint8_t> WithChannel(uint8_t channel, const std::vector<uint8_t>& message) {
  // Sized once and copied into (GCC 12 -Warray-bounds misreads insert into a 1-byte vector).
  std::vector<uint8_t> input(message.size() + 1);
  input[0] = channel;
  std::copy(message.begin(), message.end(), input.begin() + 1);
  return input;
}

}  // namespace

const std::vector<std::string>& ServerNodeChannels() {
  static const std::vector<std::string> channels = {"ANCHORMAP_KEYFRAMES", "ANCHORMAP_ENCOUNTERS",
                                                    "ANCHORMAP_MERGED_MAP"};
  return channels;
}

const std::vector<std::string>& AgentNodeChannels() {
  static const std::vector<std::string> channels = {"R1_ODOMETRY", "R1_LASER", "R1_ENCOUNTER",
                                                    "ANCHORMAP_ENCOUNTERS", "R2_LASER"};
  return channels;
}

Authenticator FuzzAuthenticator(const std::string& sender) {
  Result<KeyRing> keys = ParseKeyRing("fuzz " + std::string(64, '7'));
  AuthenticatorOptions options;
  options.sender = sender;
  options.first_counter = 1000;
  options.max_senders = 64;
  return std::move(*Authenticator::Create(std::move(*keys), options));
}

std::map<std::string, std::vector<std::vector<uint8_t>>> SeedInputs() {
  std::map<std::string, std::vector<std::vector<uint8_t>>> seeds;
  const Encounter encounter{kEpoch + 1'000'000,
                            "R1",
                            11,
                            "R2",
                            Pose2(1.0, 0.5, 0.2),
                            Eigen::Vector3d(0.04, 0.04, 0.01).asDiagonal()};
  for (int i = 0; i < 3; ++i) {
    seeds["odometry"].push_back(EncodeOdometry({kEpoch + 20'000 * i, Pose2(0.1 * i, 0, 0.01 * i)}));
    seeds["laser"].push_back(EncodeLaser(MakeScan(10 + 50 * i, kEpoch + 20'000 * i)));
    seeds["keyframe"].push_back(EncodeKeyframe(MakeKeyframe("R" + std::to_string(i + 1), 10, i)));
  }
  seeds["encounter"].push_back(EncodeEncounter(encounter));
  MergedMap map;
  map.utime = kEpoch;
  map.update = 4;
  map.trajectories.push_back(MergedTrajectory{
      "R1", 11, true, Pose2(1, 2, 0.3), {kEpoch, kEpoch + 1}, {Pose2(), Pose2(1, 0, 0)}});
  map.trajectories.push_back(MergedTrajectory{"R2", 12, false, Pose2(), {}, {}});
  map.encounters.push_back({"R1", 11, 1, "R2", 12, 0, ConstraintKind::kDirectEncounter});
  map.encounters.push_back({"R1", 11, 0, "R2", 12, 0, ConstraintKind::kScanEncounter});
  map.encounters.push_back({"R1", 11, 0, "R1", 11, 1, ConstraintKind::kLoopClosure});
  seeds["merged_map"].push_back(EncodeMergedMap(map));
  // The same map as the server sends it: chunks of 1 pose (R1's two poses in two chunks).
  MapChunkerOptions chunking;
  chunking.chunk_poses = 1;
  const MapChunker::Split split = MapChunker(chunking).Update(map, /*full=*/true);
  seeds["merged_map_header"].push_back(EncodeMergedMapHeader(split.header));
  for (const MergedMapChunk& chunk : split.chunks) {
    seeds["merged_map_chunk"].push_back(EncodeMergedMapChunk(chunk));
  }
  AnchorCovariances anchors;
  anchors.utime = kEpoch;
  anchors.anchors.push_back({"R1", 11, Pose2(1, 2, 0.3), Eigen::Matrix3d::Identity() * 0.1});
  seeds["anchor_covariances"].push_back(EncodeAnchorCovariances(anchors));
  GridTile tile;
  tile.width = 8;
  tile.height = 4;
  tile.cells.assign(32, -1);
  tile.cells[5] = 100;
  seeds["grid_tile"].push_back(EncodeGridTile(tile));
  ServerStatus status;
  status.instance_id = 4242;
  status.kernel_drops = 3;
  status.num_robots = 2;
  status.rejections = {{"not_finite", 3}, {"replay", 1}};
  seeds["server_status"].push_back(EncodeServerStatus(status));
  Authenticator sealer = FuzzAuthenticator("R1");
  for (const auto& message : {seeds["keyframe"][0], seeds["encounter"][0]}) {
    seeds["signed"].push_back(sealer.Seal("C", message.data(), message.size()));
  }
  // Node targets: a short trajectory per robot and an encounter (server); odometry, scans
  // and encounters of R1 (agent).
  for (int seq = 0; seq < 4; ++seq) {
    seeds["server_node"].push_back(WithChannel(0, EncodeKeyframe(MakeKeyframe("R1", 11, seq))));
    seeds["server_node"].push_back(WithChannel(0, EncodeKeyframe(MakeKeyframe("R2", 12, seq))));
  }
  seeds["server_node"].push_back(WithChannel(1, EncodeEncounter(encounter)));
  for (int i = 0; i < 5; ++i) {
    seeds["agent_node"].push_back(
        WithChannel(0, EncodeOdometry({kEpoch + 100'000 * i, Pose2(0.3 * i, 0, 0.02 * i)})));
    seeds["agent_node"].push_back(WithChannel(1, EncodeLaser(MakeScan(61, kEpoch + 100'000 * i))));
  }
  seeds["agent_node"].push_back(WithChannel(2, EncodeEncounter(encounter)));
  Encounter observed = encounter;
  std::swap(observed.observer, observed.observed);
  seeds["agent_node"].push_back(WithChannel(3, EncodeEncounter(observed)));
  return seeds;
}

}  // namespace anchormap::fuzz
