#pragma once
// Reading and writing LCM log files (the format of lcm-logger / lcm-logplayer) with
// typed messages. Used by the offline server, the simulator, the importer and the tools.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/util/status.h"

namespace anchormap {

struct LogEvent {
  int64_t utime = 0;
  std::string channel;
  std::vector<uint8_t> data;
};

class LcmLogWriter {
 public:
  LcmLogWriter();
  ~LcmLogWriter();
  Status Open(const std::string& path);  // truncates
  Status WriteRaw(const std::string& channel, int64_t utime, const void* data, size_t size);
  // T is an lcm-gen C++ type.
  template <typename T>
  Status Write(const std::string& channel, int64_t utime, const T& message) {
    std::vector<uint8_t> buffer(message.getEncodedSize());
    message.encode(buffer.data(), 0, static_cast<int>(buffer.size()));
    return WriteRaw(channel, utime, buffer.data(), buffer.size());
  }
  // Hands what was written to the kernel (a reader following the file sees it).
  Status Flush();
  void Close();

 private:
  struct File;
  std::unique_ptr<File> file_;
};

// Reads the LCM event log format itself (each event: sync word 0xEDA1DA01, event number,
// timestamp, channel length, data length, channel, data; big-endian) so that a corrupt
// stretch is reported and skipped rather than ending the file silently: a header that
// is not plausible (bad sync word, channel length outside 1..1024, data running past the
// end of the file) is a problem naming its byte offset, and reading resumes at the next
// sync word that starts a plausible header.
class LcmLogReader {
 public:
  LcmLogReader();
  ~LcmLogReader();
  Status Open(const std::string& path);
  // The next good event, or nullopt at the end of the file (or when nothing is open).
  std::optional<LogEvent> Next();
  // Corrupt stretches met so far, one line each: "corrupt event at byte 1234 (bad sync
  // word): skipped 56 bytes to the next event at byte 1290", or "... at the end of the
  // file". Empty for a sound log.
  const std::vector<std::string>& problems() const { return problems_; }
  // The byte just past the last good event returned by Next() (0 before the first): where
  // a writer appending to a log whose tail was cut short should continue.
  uint64_t end_of_last_event() const { return end_of_last_event_; }

 private:
  struct File;
  std::unique_ptr<File> file_;
  std::vector<std::string> problems_;
  uint64_t end_of_last_event_ = 0;
};

// Decodes an event's payload as T; nullopt when it does not decode (wrong type, truncated).
template <typename T>
std::optional<T> DecodeAs(const LogEvent& event) {
  T message;
  const int used = message.decode(event.data.data(), 0, static_cast<int>(event.data.size()));
  if (used < 0 || used != static_cast<int>(event.data.size())) return std::nullopt;
  return message;
}

}  // namespace anchormap
