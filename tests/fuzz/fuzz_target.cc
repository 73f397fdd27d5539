// One libFuzzer target per build (tests/fuzz/CMakeLists.txt defines ANCHORMAP_FUZZ_<name>).
// Decoder targets: no crash, no sanitizer report, and every accepted message is a fixed
// point after one re-encoding (decode(encode(v)) encodes to the same bytes): a failure
// aborts. Node targets: byte 0 picks the channel, the rest is handed to the node's
// OnMessage, as the LCM loop would; nothing may crash, and state stays bounded.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "agent/node/agent_node.h"
#include "common/bus/authenticator.h"
#include "common/bus/codec.h"
#include "common/bus/map_codec.h"
#include "common/util/log.h"
#include "server/node/server_node.h"
#include "tests/fuzz/fuzz_samples.h"

namespace anchormap::fuzz {
namespace {

[[noreturn, maybe_unused]] void Fail(const char* what) {
  std::fprintf(stderr, "fuzz property violated: %s\n", what);
  std::abort();
}

template <typename T, typename Decode, typename Encode>
void RoundTrip(const uint8_t* data, size_t size, Decode decode, Encode encode) {
  const Result<T> value = decode(data, size);
  if (!value.ok()) {
    if (static_cast<int>(value.status().code()) >= static_cast<int>(ErrorCode::kNumCodes)) {
      Fail("refusal without a known code");
    }
    return;
  }
  const std::vector<uint8_t> once = encode(*value);
  const Result<T> again = decode(once.data(), once.size());
  if (!again.ok()) Fail("a re-encoded accepted message does not decode");
  if (encode(*again) != once) Fail("re-encoding is not a fixed point");
}

void Quiet() {
  static const bool once = [] {
    SetMinLogLevel(LogLevel::kError);
    return true;
  }();
  (void)once;
}

}  // namespace
}  // namespace anchormap::fuzz

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace anchormap;
  using namespace anchormap::fuzz;
  Quiet();
#if defined(ANCHORMAP_FUZZ_odometry)
  // The heading travels as a quaternion: yaw -> quaternion -> yaw is exact to rounding only,
  // so the fixed point is checked on values, the heading to 1e-12 rad.
  const Result<OdometrySample> value = DecodeOdometry(data, size);
  if (value.ok()) {
    const std::vector<uint8_t> once = EncodeOdometry(*value);
    const Result<OdometrySample> again = DecodeOdometry(once.data(), once.size());
    if (!again.ok()) Fail("a re-encoded odometry sample does not decode");
    const Pose2 a = value->T_odom_body, b = again->T_odom_body;
    if (again->utime != value->utime || a.x() != b.x() || a.y() != b.y() ||
        std::abs(std::remainder(a.theta() - b.theta(), 2 * kPi)) > 1e-12) {
      Fail("odometry does not survive a re-encoding");
    }
  }
#elif defined(ANCHORMAP_FUZZ_laser)
  RoundTrip<LaserScan>(data, size, DecodeLaser, EncodeLaser);
#elif defined(ANCHORMAP_FUZZ_keyframe)
  RoundTrip<Keyframe>(data, size, DecodeKeyframe, EncodeKeyframe);
#elif defined(ANCHORMAP_FUZZ_encounter)
  RoundTrip<Encounter>(data, size, DecodeEncounter, EncodeEncounter);
#elif defined(ANCHORMAP_FUZZ_merged_map)
  RoundTrip<MergedMap>(data, size, DecodeMergedMap, EncodeMergedMap);
#elif defined(ANCHORMAP_FUZZ_merged_map_header)
  RoundTrip<MergedMapHeader>(data, size, DecodeMergedMapHeader, EncodeMergedMapHeader);
#elif defined(ANCHORMAP_FUZZ_merged_map_chunk)
  RoundTrip<MergedMapChunk>(data, size, DecodeMergedMapChunk, EncodeMergedMapChunk);
#elif defined(ANCHORMAP_FUZZ_anchor_covariances)
  RoundTrip<AnchorCovariances>(data, size, DecodeAnchorCovariances, EncodeAnchorCovariances);
#elif defined(ANCHORMAP_FUZZ_grid_tile)
  RoundTrip<GridTile>(data, size, DecodeGridTile, EncodeGridTile);
#elif defined(ANCHORMAP_FUZZ_server_status)
  RoundTrip<ServerStatus>(data, size, DecodeServerStatus, EncodeServerStatus);
#elif defined(ANCHORMAP_FUZZ_signed)
  // A fresh receiver per input (the replay window is tested elsewhere): arbitrary bytes
  // must be refused unless they are a sound envelope; the input sealed must open intact.
  Authenticator receiver = FuzzAuthenticator("server");
  (void)receiver.Open("C", data, size);
  // A sender no seed names (a seed from "R1" opened above would make R1's counter 1000 a
  // replay); the fuzzer cannot forge this sender's envelopes without the key.
  static Authenticator sender = FuzzAuthenticator("SEALER");
  const std::vector<uint8_t> sealed = sender.Seal("C", data, size);
  Result<std::vector<uint8_t> > opened = receiver.Open("C", sealed.data(), sealed.size());
  if (!opened.ok() || *opened != std::vector<uint8_t>(data, data + size)) {
    Fail("a sealed input does not open to itself");
  }
  if (receiver.Open("C", sealed.data(), sealed.size()).ok()) Fail("a replay was accepted");
#elif defined(ANCHORMAP_FUZZ_server_node)
  if (size < 1) return 0;
  static ServerNode* node = [] {
    ServerOptions options;
    options.max_robots = 8;
    options.max_trajectories = 16;
    return new ServerNode(
        options, [](const std::string&, const std::vector<uint8_t>&) {},
        [] { return int64_t{1'700'000'100'000'000}; });
  }();
  static int64_t calls = 0;
  const std::vector<std::string>& channels = ServerNodeChannels();
  node->OnMessage(channels[data[0] % channels.size()], data + 1, size - 1);
  if (++calls % 64 == 0) node->PublishAll();  // the outputs of whatever was accepted
#elif defined(ANCHORMAP_FUZZ_agent_node)
  if (size < 1) return 0;
  static AgentNode* node = [] {
    AgentNodeOptions options;
    options.agent.robot = "R1";
    options.agent.trajectory_id = 11;
    return new AgentNode(options, [](const std::string&, const std::vector<uint8_t>&) {});
  }();
  const std::vector<std::string>& channels = AgentNodeChannels();
  node->OnMessage(channels[data[0] % channels.size()], data + 1, size - 1);
#else
#error "define one ANCHORMAP_FUZZ_<target>"
#endif
  return 0;
}
