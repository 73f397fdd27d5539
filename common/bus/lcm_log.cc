#include "common/bus/lcm_log.h"

#include <lcm/eventlog.h>

namespace anchormap {

struct LcmLogWriter::File {
  lcm_eventlog_t* log = nullptr;
};
struct LcmLogReader::File {
  lcm_eventlog_t* log = nullptr;
};

LcmLogWriter::LcmLogWriter() : file_(std::make_unique<File>()) {}
LcmLogWriter::~LcmLogWriter() { Close(); }

Status LcmLogWriter::Open(const std::string& path) {
  Close();
  file_->log = lcm_eventlog_create(path.c_str(), "w");
  if (!file_->log) return Status::Error("cannot open LCM log '" + path + "' for writing");
  return Status::Ok();
}

Status LcmLogWriter::WriteRaw(const std::string& channel, int64_t utime, const void* data,
                              size_t size) {
  if (!file_->log) return Status::Error("LCM log is not open");
  lcm_eventlog_event_t event{};
  event.timestamp = utime;
  event.channellen = static_cast<int32_t>(channel.size());
  event.channel = const_cast<char*>(channel.c_str());
  event.datalen = static_cast<int32_t>(size);
  event.data = const_cast<void*>(data);
  if (lcm_eventlog_write_event(file_->log, &event) != 0) {
    return Status::Error("write to LCM log failed");
  }
  return Status::Ok();
}

void LcmLogWriter::Close() {
  if (file_ && file_->log) {
    lcm_eventlog_destroy(file_->log);
    file_->log = nullptr;
  }
}

LcmLogReader::LcmLogReader() : file_(std::make_unique<File>()) {}
LcmLogReader::~LcmLogReader() {
  if (file_->log) lcm_eventlog_destroy(file_->log);
}

Status LcmLogReader::Open(const std::string& path) {
  if (file_->log) lcm_eventlog_destroy(file_->log);
  file_->log = lcm_eventlog_create(path.c_str(), "r");
  if (!file_->log) return Status::Error("cannot open LCM log '" + path + "' for reading");
  return Status::Ok();
}

std::optional<LogEvent> LcmLogReader::Next() {
  if (!file_->log) return std::nullopt;
  lcm_eventlog_event_t* event = lcm_eventlog_read_next_event(file_->log);
  if (!event) return std::nullopt;
  LogEvent out;
  out.utime = event->timestamp;
  out.channel.assign(event->channel, event->channellen);
  const auto* bytes = static_cast<const uint8_t*>(event->data);
  out.data.assign(bytes, bytes + event->datalen);
  lcm_eventlog_free_event(event);
  return out;
}

}  // namespace anchormap
