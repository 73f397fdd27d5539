#include "server/recorded_match_codec.h"

#include <cstring>
#include <string>
#include <type_traits>

namespace anchormap {
namespace {

constexpr char kMagic[4] = {'A', 'M', 'M', 'R'};
constexpr uint32_t kVersion = 1;

class Writer {
 public:
  template <typename T>
  void Put(T value) {
    static_assert(std::is_trivially_copyable<T>::value, "plain values only");
    const size_t at = bytes_.size();
    bytes_.resize(at + sizeof(T));
    std::memcpy(bytes_.data() + at, &value, sizeof(T));
  }
  void Key(const PoseKey& key) {
    Put<int64_t>(key.trajectory.value());
    Put<int32_t>(key.index);
  }
  void Pose(const Pose2& pose) {
    Put(pose.x());
    Put(pose.y());
    Put(pose.theta());
  }
  std::vector<uint8_t> Take() { return std::move(bytes_); }

 private:
  std::vector<uint8_t> bytes_;
};

// A read past the end fails once and for all; the caller checks failed() at the end.
class Reader {
 public:
  Reader(const uint8_t* data, size_t size) : data_(data), size_(size) {}
  template <typename T>
  T Get() {
    T value{};
    if (failed_ || size_ - pos_ < sizeof(T)) {
      failed_ = true;
      return value;
    }
    std::memcpy(&value, data_ + pos_, sizeof(T));
    pos_ += sizeof(T);
    return value;
  }
  PoseKey Key() {
    PoseKey key;
    key.trajectory = TrajectoryId(Get<int64_t>());
    key.index = Get<int32_t>();
    return key;
  }
  Pose2 Pose() {
    const double x = Get<double>();
    const double y = Get<double>();
    return Pose2(x, y, Get<double>());
  }
  bool failed() const { return failed_; }
  size_t left() const { return size_ - pos_; }

 private:
  const uint8_t* data_;
  size_t size_;
  size_t pos_ = 0;
  bool failed_ = false;
};

}  // namespace

std::vector<uint8_t> EncodeRecordedMatch(const RecordedMatch& match) {
  Writer w;
  for (const char c : kMagic) w.Put(c);
  w.Put(kVersion);
  w.Put<int64_t>(match.ordinal);
  w.Key(match.tag.query);
  w.Key(match.tag.reference);
  w.Put<uint8_t>(match.result ? 1 : 0);
  if (match.result) {
    const MatchResult& r = *match.result;
    w.Pose(r.pose);
    w.Put(r.score);
    w.Put(r.overlap);
    for (int i = 0; i < 9; ++i) w.Put(r.covariance(i / 3, i % 3));
    w.Pose(r.lattice_pose);
    w.Put<int64_t>(r.search.scored_nodes);
    w.Put<int64_t>(r.search.leaves);
    w.Pose(r.window.center);
    w.Put(r.window.angle_step_rad);
    w.Put<int32_t>(r.window.half_angles);
    w.Put<int32_t>(r.window.half_cells_x);
    w.Put<int32_t>(r.window.half_cells_y);
    w.Put<int32_t>(r.lattice.k);
    w.Put<int32_t>(r.lattice.dx);
    w.Put<int32_t>(r.lattice.dy);
    w.Put(r.lattice.score);
  }
  return w.Take();
}

Result<RecordedMatch> DecodeRecordedMatch(const uint8_t* data, size_t size) {
  Reader r(data, size);
  for (const char c : kMagic) {
    if (r.Get<char>() != c) {
      return Status::Error(ErrorCode::kDecodeFailed, "recorded match: not one (magic)");
    }
  }
  const uint32_t version = r.Get<uint32_t>();
  if (!r.failed() && version != kVersion) {
    return Status::Error(ErrorCode::kDecodeFailed, "recorded match: version " +
                                                       std::to_string(version) + ", this reads " +
                                                       std::to_string(kVersion));
  }
  RecordedMatch match;
  match.ordinal = r.Get<int64_t>();
  match.tag.query = r.Key();
  match.tag.reference = r.Key();
  const uint8_t has_result = r.Get<uint8_t>();
  if (has_result > 1) {
    return Status::Error(ErrorCode::kDecodeFailed, "recorded match: bad result flag");
  }
  if (has_result == 1) {
    MatchResult m;
    m.pose = r.Pose();
    m.score = r.Get<double>();
    m.overlap = r.Get<double>();
    for (int i = 0; i < 9; ++i) m.covariance(i / 3, i % 3) = r.Get<double>();
    m.lattice_pose = r.Pose();
    m.search.scored_nodes = r.Get<int64_t>();
    m.search.leaves = r.Get<int64_t>();
    m.window.center = r.Pose();
    m.window.angle_step_rad = r.Get<double>();
    m.window.half_angles = r.Get<int32_t>();
    m.window.half_cells_x = r.Get<int32_t>();
    m.window.half_cells_y = r.Get<int32_t>();
    m.lattice.k = r.Get<int32_t>();
    m.lattice.dx = r.Get<int32_t>();
    m.lattice.dy = r.Get<int32_t>();
    m.lattice.score = r.Get<double>();
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
