#pragma once
// Plain values to and from bytes, for the server's own binary records (snapshots, journaled
// match results): one writer and one reader, so every record has the same rules (host byte
// order, a read past the end latches a failure the caller checks once at the end).

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "common/geometry/pose2.h"

namespace anchormap {

// Little-endian writer of plain values.
class ByteWriter {
 public:
  std::vector<uint8_t>& bytes() { return bytes_; }
  std::vector<uint8_t> Take() { return std::move(bytes_); }
  template <typename T>
  void Raw(T value) {
    static_assert(std::is_trivially_copyable<T>::value, "plain values only");
    const size_t at = bytes_.size();
    bytes_.resize(at + sizeof(T));
    std::memcpy(bytes_.data() + at, &value, sizeof(T));
  }
  void I64(int64_t v) { Raw(v); }
  void I32(int32_t v) { Raw(v); }
  void U8(uint8_t v) { Raw(v); }
  void F64(double v) { Raw(v); }
  void Bool(bool v) { U8(v ? 1 : 0); }
  void Size(size_t n) { Raw(static_cast<uint64_t>(n)); }
  void String(const std::string& s) {
    Size(s.size());
    bytes_.insert(bytes_.end(), s.begin(), s.end());
  }
  void Pose(const Pose2& p) {
    F64(p.x());
    F64(p.y());
    F64(p.theta());
  }
  void Matrix(const Eigen::Matrix3d& m) {
    for (int i = 0; i < 9; ++i) F64(m(i / 3, i % 3));
  }

 private:
  std::vector<uint8_t> bytes_;
};

// The matching reader: a read past the end (or an absurd count) fails once and for all;
// the caller checks failed() at the end.
class ByteReader {
 public:
  ByteReader(const uint8_t* data, size_t size) : data_(data), size_(size) {}
  template <typename T>
  T Raw() {
    T value{};
    if (failed_ || size_ - pos_ < sizeof(T)) {
      failed_ = true;
      return value;
    }
    std::memcpy(&value, data_ + pos_, sizeof(T));
    pos_ += sizeof(T);
    return value;
  }
  int64_t I64() { return Raw<int64_t>(); }
  int32_t I32() { return Raw<int32_t>(); }
  uint8_t U8() { return Raw<uint8_t>(); }
  double F64() { return Raw<double>(); }
  bool Bool() { return U8() != 0; }
  // A count of items of at least `min_item_bytes` each: refused when the rest cannot hold
  // them (a corrupt count must not allocate gigabytes).
  size_t Count(size_t min_item_bytes = 1) {
    const uint64_t n = Raw<uint64_t>();
    if (failed_ || n > (size_ - pos_) / std::max<size_t>(1, min_item_bytes)) {
      failed_ = true;
      return 0;
    }
    return static_cast<size_t>(n);
  }
  std::string String() {
    const size_t n = Count();
    if (failed_) return {};
    std::string s(reinterpret_cast<const char*>(data_ + pos_), n);
    pos_ += n;
    return s;
  }
  Pose2 Pose() {
    const double x = F64();
    const double y = F64();
    return Pose2(x, y, F64());
  }
  Eigen::Matrix3d Matrix() {
    Eigen::Matrix3d m;
    for (int i = 0; i < 9; ++i) m(i / 3, i % 3) = F64();
    return m;
  }
  bool failed() const { return failed_; }
  // A value read whole but refused by its reader (a nested record that does not decode).
  void Fail() { failed_ = true; }
  bool at_end() const { return pos_ == size_; }
  size_t left() const { return size_ - pos_; }

 private:
  const uint8_t* data_;
  size_t size_;
  size_t pos_ = 0;
  bool failed_ = false;
};

}  // namespace anchormap
