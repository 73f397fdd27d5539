#pragma once
// The server's write-ahead journal (issue 13, crash recovery): one LCM event log,
// DIR/journal.lcmlog, that lcm-logplayer can read. Every input the server is about to apply
// is appended first, in the order applied, stamped with the server's clock at that moment,
// and flushed to the kernel before Append returns: a SIGKILL afterwards loses nothing
// appended (the kernel holds the bytes; a power cut is another matter: no fsync). Each
// event goes to the kernel in one write(2) (a stdio buffer larger than any event, flushed
// per event), so a kill cannot leave half an event in practice; if a tail was cut short
// anyway (a full disk, a power cut), Open drops it with a warning and appends from the last
// whole event. Corruption before the tail is an error: the server must not guess. One
// process at a time: Open takes an exclusive lock (flock on DIR/journal.lock, released
// by the kernel when the process dies, SIGKILL included), so two servers started on one
// directory cannot interleave their inputs.
//
// What the events mean is the server node's business (server/node/server_node.h); this
// file only stores them.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "common/bus/lcm_log.h"
#include "common/util/status.h"

namespace anchormap {

class Journal {
 public:
  ~Journal();

  // Opens (creating DIR and the file if needed) for appending; the events already in the
  // journal, in order, go to `*existing`. kIoError when another process holds it.
  static Result<std::unique_ptr<Journal>> Open(const std::string& dir,
                                               std::vector<LogEvent>* existing);

  // Appends one event and flushes it to the kernel. A failure means nothing durable was
  // written (the caller must then not apply the input).
  Status Append(const std::string& channel, int64_t utime, const uint8_t* data, size_t size);

  const std::string& path() const { return path_; }
  int64_t events() const { return events_; }  // in the file, old and new
  int64_t bytes() const { return bytes_; }    // size of the file

 private:
  Journal() = default;
  struct File;
  std::unique_ptr<File> file_;
  std::string path_;
  int64_t events_ = 0;
  int64_t bytes_ = 0;
};

}  // namespace anchormap
