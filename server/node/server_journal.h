#pragma once
// The online server's journal (crash recovery, common/bus/journal.h) and its periodic
// snapshots (server/snapshot_codec.h, snapshot_store.h): opened and replayed at start,
// then every input the node accepts is appended before it is applied, and a snapshot is
// encoded between two events when one is due and written to disk off the loop.

#include <chrono>
#include <cstdint>
#include <future>
#include <memory>
#include <mutex>
#include <string>

#include "common/bus/journal.h"
#include "common/util/status.h"
#include "server/node/server_node.h"
#include "server/node/server_options.h"
#include "server/snapshot_codec.h"

namespace anchormap {

class ServerJournal {
 public:
  // Opens the journal in `dir`, restores the newest valid snapshot there (a refused one is
  // logged and the next older tried), replays the journal after it through `node` (the
  // same handlers, with the clocks they saw live) and has `node` journal every input from
  // now on. `node` must outlive the returned journal's use.
  static Result<std::unique_ptr<ServerJournal>> OpenAndReplay(const std::string& dir,
                                                              bool defer_updates, ServerNode* node);
  // Waits for a snapshot still being written; the node journals nothing more.
  ~ServerJournal();

  // From the loop's timer (between two events, so the state is the journal prefix's):
  // a snapshot when `options.snapshot_every_*` says one is due and none is being written.
  void SnapshotIfDue(const ServerOptions& options, ServerNode* node);
  // Waits for (and logs) a snapshot still being written.
  void WaitForSnapshotWrite() { CollectSnapshotWrite(/*wait=*/true); }
  // "journal N events B bytes, snapshot at E", for the status line.
  std::string StatusText() const;

 private:
  ServerJournal() = default;
  // Logs the snapshot written off the loop once it is done (`wait`: also if it is not
  // yet); true when none is in flight any more.
  bool CollectSnapshotWrite(bool wait);

  struct Written {
    Status status;
    double seconds = 0.0;
  };

  ServerNode* node_ = nullptr;
  // Appends come from the loop and from the match workers (match results).
  mutable std::mutex append_mutex_;
  std::unique_ptr<Journal> journal_;
  std::string dir_;
  JournalPosition last_;          // the journal's length and its last event
  int64_t snapshot_events_ = -1;  // journal events the newest snapshot covers (-1: none)
  std::chrono::steady_clock::time_point snapshot_time_ = std::chrono::steady_clock::now();
  // The snapshot file being written (its write + fsync can take longer than the encoding
  // on a busy disk); at most one at a time.
  std::future<Written> writing_;
  std::string writing_what_;  // for the log line once written
};

}  // namespace anchormap
