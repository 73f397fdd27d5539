#include "server/recorded_match_codec.h"

#include <string>

#include "server/byte_codec.h"

namespace anchormap {
namespace {

constexpr char kMagic[4] = {'A', 'M', 'M', 'R'};
// Version 2 adds the search's kind to the tag and the options fingerprint. Version 1
// records (journals written before) are still read, with kind kUnknown and fingerprint 0:
// a server never reuses them (it cannot know their options), it matches again.
constexpr uint32_t kVersion = 2;
constexpr uint32_t kOldestVersion = 1;

void PutKey(ByteWriter* w, const PoseKey& key) {
  w->I64(key.trajectory.value());
  w->I32(key.index);
}
PoseKey GetKey(ByteReader* r) {
  PoseKey key;
  key.trajectory = TrajectoryId(r->I64());
  key.index = r->I32();
  return key;
}

}  // namespace

std::vector<uint8_t> EncodeRecordedMatch(const RecordedMatch& match) {
  ByteWriter w;
  for (const char c : kMagic) w.Raw(c);
  w.Raw(kVersion);
  w.Raw<int64_t>(match.ordinal);
  PutKey(&w, match.tag.query);
  PutKey(&w, match.tag.reference);
  w.Raw<uint8_t>(static_cast<uint8_t>(match.tag.kind));
  w.Raw<uint64_t>(match.options_fingerprint);
  w.Raw<uint8_t>(match.result ? 1 : 0);
  if (match.result) {
    const MatchResult& r = *match.result;
    w.Pose(r.pose);
    w.Raw(r.score);
    w.Raw(r.overlap);
    w.Matrix(r.covariance);
    w.Pose(r.lattice_pose);
    w.Raw<int64_t>(r.search.scored_nodes);
    w.Raw<int64_t>(r.search.leaves);
    w.Pose(r.window.center);
    w.Raw(r.window.angle_step_rad);
    w.Raw<int32_t>(r.window.half_angles);
    w.Raw<int32_t>(r.window.half_cells_x);
    w.Raw<int32_t>(r.window.half_cells_y);
    w.Raw<int32_t>(r.lattice.k);
    w.Raw<int32_t>(r.lattice.dx);
    w.Raw<int32_t>(r.lattice.dy);
    w.Raw(r.lattice.score);
  }
  return w.Take();
}

Result<RecordedMatch> DecodeRecordedMatch(const uint8_t* data, size_t size) {
  ByteReader r(data, size);
  for (const char c : kMagic) {
    if (r.Raw<char>() != c) {
      return Status::Error(ErrorCode::kDecodeFailed, "recorded match: not one (magic)");
    }
  }
  const uint32_t version = r.Raw<uint32_t>();
  if (!r.failed() && (version < kOldestVersion || version > kVersion)) {
    return Status::Error(ErrorCode::kDecodeFailed,
                         "recorded match: version " + std::to_string(version) + ", this reads " +
                             std::to_string(kOldestVersion) + " to " + std::to_string(kVersion));
  }
  RecordedMatch match;
  match.ordinal = r.Raw<int64_t>();
  match.tag.query = GetKey(&r);
  match.tag.reference = GetKey(&r);
  if (version >= 2) {
    const uint8_t kind = r.Raw<uint8_t>();
    if (!r.failed() && (kind == 0 || kind > kLastMatchKind)) {
      return Status::Error(ErrorCode::kDecodeFailed,
                           "recorded match: bad kind " + std::to_string(kind));
    }
    match.tag.kind = static_cast<MatchKind>(kind);
    match.options_fingerprint = r.Raw<uint64_t>();
  }
  const uint8_t has_result = r.Raw<uint8_t>();
  if (has_result > 1) {
    return Status::Error(ErrorCode::kDecodeFailed, "recorded match: bad result flag");
  }
  if (has_result == 1) {
    MatchResult m;
    m.pose = r.Pose();
    m.score = r.Raw<double>();
    m.overlap = r.Raw<double>();
    m.covariance = r.Matrix();
    m.lattice_pose = r.Pose();
    m.search.scored_nodes = r.Raw<int64_t>();
    m.search.leaves = r.Raw<int64_t>();
    m.window.center = r.Pose();
    m.window.angle_step_rad = r.Raw<double>();
    m.window.half_angles = r.Raw<int32_t>();
    m.window.half_cells_x = r.Raw<int32_t>();
    m.window.half_cells_y = r.Raw<int32_t>();
    m.lattice.k = r.Raw<int32_t>();
    m.lattice.dx = r.Raw<int32_t>();
    m.lattice.dy = r.Raw<int32_t>();
    m.lattice.score = r.Raw<double>();
    match.result = m;
  }
  if (r.failed()) return Status::Error(ErrorCode::kDecodeFailed, "recorded match: truncated");
  if (r.left() != 0) {
    return Status::Error(ErrorCode::kDecodeFailed,
                         "recorded match: " + std::to_string(r.left()) + " bytes left over");
  }
  return match;
}

}  // namespace anchormap
