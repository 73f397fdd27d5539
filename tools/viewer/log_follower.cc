#include "tools/viewer/log_follower.h"

#include <sys/stat.h>

#include <algorithm>
#include <cstring>
#include <utility>

namespace anchormap::viewer {
namespace {

constexpr uint8_t kSync[4] = {0xED, 0xA1, 0xDA, 0x01};
constexpr size_t kHeaderBytes = 4 + 8 + 8 + 4 + 4;

uint64_t ReadBigEndian(const uint8_t* p, int bytes) {
  uint64_t v = 0;
  for (int i = 0; i < bytes; ++i) v = (v << 8) | p[i];
  return v;
}

}  // namespace

LogFollower::LogFollower(std::string path) : path_(std::move(path)) {}

LogFollower::~LogFollower() {
  if (file_) std::fclose(file_);
}

bool LogFollower::Reopen() {
  if (file_) std::fclose(file_);
  file_ = std::fopen(path_.c_str(), "rb");
  offset_ = 0;
  pending_.clear();
  if (!file_) return false;
  struct stat info;
  inode_ = fstat(fileno(file_), &info) == 0 ? static_cast<uint64_t>(info.st_ino) : 0;
  return true;
}

std::vector<FollowedEvent> LogFollower::Poll(size_t max_events) {
  std::vector<FollowedEvent> out;
  struct stat info;
  const bool exists = stat(path_.c_str(), &info) == 0;
  if (!exists) return out;
  if (!file_ || static_cast<uint64_t>(info.st_ino) != inode_ || info.st_size < offset_) {
    if (file_) ++reopens_;
    if (!Reopen()) return out;
  }
  // Read what was appended (bounded per call, so that one poll never holds a huge file).
  uint8_t chunk[1 << 16];
  size_t budget = 64u << 20;
  std::clearerr(file_);
  while (budget > 0) {
    const size_t n = std::fread(chunk, 1, std::min(sizeof(chunk), budget), file_);
    if (n == 0) break;
    pending_.insert(pending_.end(), chunk, chunk + n);
    offset_ += static_cast<int64_t>(n);
    budget -= n;
  }
  size_t pos = 0;
  while (out.size() < max_events) {
    if (pending_.size() - pos < kHeaderBytes) break;
    const uint8_t* p = pending_.data() + pos;
    if (std::memcmp(p, kSync, 4) != 0) {
      ++pos;
      ++bytes_skipped_;
      continue;
    }
    const uint32_t channel_length = static_cast<uint32_t>(ReadBigEndian(p + 20, 4));
    const uint32_t data_length = static_cast<uint32_t>(ReadBigEndian(p + 24, 4));
    if (channel_length == 0 || channel_length > kMaxChannelLength || data_length > kMaxDataLength) {
      ++pos;  // not an event after all
      ++bytes_skipped_;
      continue;
    }
    const size_t total = kHeaderBytes + channel_length + data_length;
    if (pending_.size() - pos < total) break;  // the rest is not written yet
    FollowedEvent event;
    event.utime = static_cast<int64_t>(ReadBigEndian(p + 12, 8));
    event.channel.assign(reinterpret_cast<const char*>(p + kHeaderBytes), channel_length);
    event.data.assign(p + kHeaderBytes + channel_length, p + total);
    out.push_back(std::move(event));
    ++events_;
    pos += total;
  }
  pending_.erase(pending_.begin(), pending_.begin() + static_cast<std::ptrdiff_t>(pos));
  return out;
}

}  // namespace anchormap::viewer
