#pragma once
// Reads an LCM log file while another process writes it (like `tail -f`): each Poll()
// returns the events completed since the last one. The viewer follows lcm-logger's file
// with it where the bus cannot reach (scripts/demo.sh --viewer: the run's bus is inside a
// private network namespace, its log file is not). The LCM event log format (every field
// big-endian): sync word 0xEDA1DA01, int64 event number, int64 utime, int32 channel
// length, int32 data length, channel, data. A half-written event waits for its rest; bytes
// that do not start an event are skipped up to the next sync word (counted). A file that
// shrinks or is replaced is read again from its start. Bus-free: no LCM library involved.

#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

namespace anchormap::viewer {

struct FollowedEvent {
  int64_t utime = 0;
  std::string channel;
  std::vector<uint8_t> data;
};

class LogFollower {
 public:
  static constexpr uint32_t kMaxChannelLength = 256;
  static constexpr uint32_t kMaxDataLength = 64u << 20;

  explicit LogFollower(std::string path);
  ~LogFollower();
  LogFollower(const LogFollower&) = delete;
  LogFollower& operator=(const LogFollower&) = delete;

  // The events completed since the last call (at most `max_events`); none while the file
  // does not exist.
  std::vector<FollowedEvent> Poll(size_t max_events = 10000);

  int64_t events() const { return events_; }
  int64_t bytes_skipped() const { return bytes_skipped_; }
  int64_t reopens() const { return reopens_; }

 private:
  bool Reopen();

  std::string path_;
  std::FILE* file_ = nullptr;
  uint64_t inode_ = 0;
  int64_t offset_ = 0;  // bytes read from the file so far
  std::vector<uint8_t> pending_;
  int64_t events_ = 0;
  int64_t bytes_skipped_ = 0;
  int64_t reopens_ = 0;
};

}  // namespace anchormap::viewer
