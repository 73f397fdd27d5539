#include "common/bus/journal.h"

#include <fcntl.h>
#include <lcm/eventlog.h>
#include <sys/file.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <system_error>

#include "common/util/log.h"

namespace anchormap {
namespace {

// Larger than any event the server accepts (a keyframe of max_scan_ranges ranges is tens
// of kB), so that each event reaches the kernel in one write(2) at the flush.
constexpr size_t kBufferBytes = size_t{4} << 20;
constexpr size_t kEventHeaderBytes = 4 + 8 + 8 + 4 + 4;

}  // namespace

struct Journal::File {
  int lock_fd = -1;
  lcm_eventlog_t* log = nullptr;
  std::vector<char> buffer;
  ~File() {
    if (log) lcm_eventlog_destroy(log);
    if (lock_fd >= 0) ::close(lock_fd);  // releases the lock
  }
};

Journal::~Journal() = default;

Result<std::unique_ptr<Journal>> Journal::Open(const std::string& dir,
                                               std::vector<LogEvent>* existing) {
  namespace fs = std::filesystem;
  std::error_code error;
  fs::create_directories(dir, error);
  if (error) {
    return Status::Error(ErrorCode::kIoError,
                         "cannot create journal directory '" + dir + "': " + error.message());
  }
  std::unique_ptr<Journal> journal(new Journal());
  journal->file_ = std::make_unique<File>();
  File& f = *journal->file_;
  const std::string lock_path = (fs::path(dir) / "journal.lock").string();
  f.lock_fd = ::open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (f.lock_fd < 0) return Status::Error(ErrorCode::kIoError, "cannot open " + lock_path);
  if (::flock(f.lock_fd, LOCK_EX | LOCK_NB) != 0) {
    return Status::Error(ErrorCode::kIoError,
                         "the journal in '" + dir + "' is in use by another process");
  }
  journal->path_ = (fs::path(dir) / "journal.lcmlog").string();
  existing->clear();
  if (fs::exists(journal->path_)) {
    LcmLogReader reader;
    if (Status s = reader.Open(journal->path_); !s.ok()) return s;
    while (std::optional<LogEvent> event = reader.Next()) {
      // Only events before the first problem count: the tail may be cut, the middle not.
      if (!reader.problems().empty()) break;
      existing->push_back(std::move(*event));
    }
    const uint64_t good = reader.end_of_last_event();
    const uint64_t size = fs::file_size(journal->path_, error);
    if (error) return Status::Error(ErrorCode::kIoError, "cannot stat " + journal->path_);
    if (good != size) {
      // The events after `good` (if any) were read past a problem: refuse rather than drop
      // accepted inputs from the middle of the history.
      LcmLogReader check;
      if (Status s = check.Open(journal->path_); !s.ok()) return s;
      int64_t all = 0;
      while (check.Next()) ++all;
      if (all != static_cast<int64_t>(existing->size())) {
        return Status::Error(
            ErrorCode::kIoError,
            journal->path_ + " is corrupt before its end (" +
                (check.problems().empty() ? std::string("?") : check.problems().front()) +
                "): refusing to resume from it");
      }
      LogWarning(journal->path_ + ": dropping a cut-short last event (" +
                 std::to_string(size - good) + " bytes after byte " + std::to_string(good) + ")");
      fs::resize_file(journal->path_, good, error);
      if (error) {
        return Status::Error(ErrorCode::kIoError,
                             "cannot truncate " + journal->path_ + ": " + error.message());
      }
    }
    journal->bytes_ = static_cast<int64_t>(good);
  }
  journal->events_ = static_cast<int64_t>(existing->size());
  f.log = lcm_eventlog_create(journal->path_.c_str(), "a");
  if (!f.log) {
    return Status::Error(ErrorCode::kIoError,
                         "cannot open journal '" + journal->path_ + "' for appending");
  }
  f.log->eventcount = journal->events_;  // event numbers continue
  f.buffer.resize(kBufferBytes);
  if (std::setvbuf(f.log->f, f.buffer.data(), _IOFBF, f.buffer.size()) != 0) {
    return Status::Error(ErrorCode::kIoError, "cannot buffer " + journal->path_);
  }
  return journal;
}

Status Journal::Append(const std::string& channel, int64_t utime, const uint8_t* data,
                       size_t size) {
  lcm_eventlog_event_t event{};
  event.timestamp = utime;
  event.channellen = static_cast<int32_t>(channel.size());
  event.channel = const_cast<char*>(channel.c_str());
  event.datalen = static_cast<int32_t>(size);
  event.data = const_cast<uint8_t*>(data);
  if (lcm_eventlog_write_event(file_->log, &event) != 0 || std::fflush(file_->log->f) != 0) {
    return Status::Error(ErrorCode::kIoError, "append to journal " + path_ + " failed");
  }
  ++events_;
  bytes_ += static_cast<int64_t>(kEventHeaderBytes + channel.size() + size);
  return Status::Ok();
}

}  // namespace anchormap
