#include "common/bus/lcm_log.h"

#include <lcm/eventlog.h>

#include <algorithm>
#include <cstdio>
#include <fstream>

namespace anchormap {

struct LcmLogWriter::File {
  lcm_eventlog_t* log = nullptr;
};
struct LcmLogReader::File {
  static constexpr uint64_t kUnknown = ~uint64_t{0};
  std::ifstream stream;
  std::vector<char> buffer;  // the stream's, larger than its default: fewer reads
  uint64_t size = 0;
  uint64_t position = 0;  // of the next event's header
  // The stream's get position (kUnknown when not known). A seek empties the stream's buffer
  // and costs a system call; the events are read in order, so reading on needs none (at 100
  // simulated robots, seeking before every header and payload was 15 % of a replay's CPU).
  uint64_t at = kUnknown;

  void SeekTo(uint64_t offset) {
    if (at == offset && stream) return;
    stream.clear();
    stream.seekg(static_cast<std::streamoff>(offset));
    at = offset;
  }
  // Reads n bytes at the stream's position; false (position unknown) when short.
  bool Read(char* data, uint64_t n) {
    if (stream.read(data, static_cast<std::streamsize>(n))) {
      at += n;
      return true;
    }
    at = kUnknown;
    return false;
  }
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

Status LcmLogWriter::Flush() {
  if (!file_->log) return Status::Error("LCM log is not open");
  if (std::fflush(file_->log->f) != 0) return Status::Error("flushing the LCM log failed");
  return Status::Ok();
}

void LcmLogWriter::Close() {
  if (file_ && file_->log) {
    lcm_eventlog_destroy(file_->log);
    file_->log = nullptr;
  }
}

LcmLogReader::LcmLogReader() : file_(std::make_unique<File>()) {}
LcmLogReader::~LcmLogReader() = default;

namespace {

constexpr uint32_t kSyncWord = 0xEDA1DA01;
constexpr size_t kHeaderBytes = 4 + 8 + 8 + 4 + 4;
constexpr int32_t kMaxChannelLength = 1024;

uint64_t BigEndian(const uint8_t* bytes, int n) {
  uint64_t value = 0;
  for (int i = 0; i < n; ++i) value = (value << 8) | bytes[i];
  return value;
}

}  // namespace

Status LcmLogReader::Open(const std::string& path) {
  file_->stream = std::ifstream();
  file_->buffer.resize(1 << 18);
  file_->stream.rdbuf()->pubsetbuf(file_->buffer.data(),
                                   static_cast<std::streamsize>(file_->buffer.size()));
  file_->stream.open(path, std::ios::binary);
  file_->at = File::kUnknown;
  problems_.clear();
  file_->position = 0;
  end_of_last_event_ = 0;
  if (!file_->stream) {
    file_->size = 0;
    return Status::Error(ErrorCode::kIoError, "cannot open LCM log '" + path + "' for reading");
  }
  file_->stream.seekg(0, std::ios::end);
  file_->size = static_cast<uint64_t>(file_->stream.tellg());
  file_->stream.seekg(0);
  return Status::Ok();
}

std::optional<LogEvent> LcmLogReader::Next() {
  File& f = *file_;
  if (!f.stream.is_open()) return std::nullopt;
  // Why the header at `offset` is not plausible, or "" when it is.
  auto check = [&f](uint64_t offset, const uint8_t* h, int32_t* channel_length,
                    int32_t* data_length) -> std::string {
    if (BigEndian(h, 4) != kSyncWord) return "bad sync word";
    *channel_length = static_cast<int32_t>(BigEndian(h + 20, 4));
    *data_length = static_cast<int32_t>(BigEndian(h + 24, 4));
    if (*channel_length < 1 || *channel_length > kMaxChannelLength) return "bad channel length";
    if (*data_length < 0) return "negative data length";
    const uint64_t end = offset + kHeaderBytes + static_cast<uint64_t>(*channel_length) +
                         static_cast<uint64_t>(*data_length);
    if (end > f.size) return "event runs past the end of the file";
    return "";
  };
  auto read_header = [&f](uint64_t offset, uint8_t* h) {
    if (offset + kHeaderBytes > f.size) return false;
    f.SeekTo(offset);
    return f.Read(reinterpret_cast<char*>(h), kHeaderBytes);
  };
  if (f.position >= f.size) return std::nullopt;
  uint8_t header[kHeaderBytes];
  int32_t channel_length = 0, data_length = 0;
  std::string why = read_header(f.position, header)
                        ? check(f.position, header, &channel_length, &data_length)
                        : "truncated header";
  if (!why.empty()) {
    // Resynchronise: the next offset whose sync word starts a plausible header.
    const uint64_t bad = f.position;
    uint64_t next = bad + 1;
    bool found = false;
    std::vector<uint8_t> window;
    for (; next + kHeaderBytes <= f.size; ++next) {
      if (!read_header(next, header)) break;
      if (check(next, header, &channel_length, &data_length).empty()) {
        found = true;
        break;
      }
      // Jump to the next candidate sync byte quickly.
      const uint64_t span = std::min<uint64_t>(f.size - next, 1 << 16);
      window.resize(span);
      f.stream.clear();
      f.stream.seekg(static_cast<std::streamoff>(next + 1));
      f.at = File::kUnknown;
      const std::streamsize got =
          f.stream
              .read(reinterpret_cast<char*>(window.data()), static_cast<std::streamsize>(span - 1))
              .gcount();
      uint64_t skip = static_cast<uint64_t>(got);
      for (std::streamsize i = 0; i < got; ++i) {
        if (window[static_cast<size_t>(i)] == 0xED) {
          skip = static_cast<uint64_t>(i);
          break;
        }
      }
      next += skip;  // the loop's ++next lands on the candidate
    }
    std::string problem = "corrupt event at byte " + std::to_string(bad) + " (" + why + "): ";
    if (!found) {
      problems_.push_back(problem + "skipped the last " + std::to_string(f.size - bad) +
                          " bytes, to the end of the file");
      f.position = f.size;
      return std::nullopt;
    }
    problems_.push_back(problem + "skipped " + std::to_string(next - bad) +
                        " bytes to the next event at byte " + std::to_string(next));
    f.position = next;
  }
  LogEvent out;
  out.utime = static_cast<int64_t>(BigEndian(header + 12, 8));
  out.channel.resize(static_cast<size_t>(channel_length));
  out.data.resize(static_cast<size_t>(data_length));
  f.SeekTo(f.position + kHeaderBytes);
  if (!f.Read(out.channel.data(), static_cast<uint64_t>(channel_length)) ||
      !f.Read(reinterpret_cast<char*>(out.data.data()), static_cast<uint64_t>(data_length))) {
    problems_.push_back("read error at byte " + std::to_string(f.position));
    f.position = f.size;
    return std::nullopt;
  }
  f.position +=
      kHeaderBytes + static_cast<uint64_t>(channel_length) + static_cast<uint64_t>(data_length);
  end_of_last_event_ = f.position;
  return out;
}

}  // namespace anchormap
