// The online server's journal and its snapshots (server_journal.h).

#include "server/node/server_journal.h"

#include <algorithm>
#include <ctime>
#include <sstream>

#include "common/util/log.h"
#include "server/node/snapshot_store.h"

namespace anchormap {
namespace {

// Restores the newest snapshot in `dir` that is valid and matches `events` (the journal);
// returns the number of events it covers (0: none usable, replay everything). A refused
// snapshot is logged with its reason and the next older one tried.
int64_t RestoreNewestSnapshot(const std::string& dir, const std::vector<LogEvent>& events,
                              ServerNode* node) {
  const std::vector<std::string> files = ListSnapshotFiles(dir);
  if (files.empty()) return 0;
  if (!node->CanSnapshot()) {
    LogWarning("journal " + dir + ": " + std::to_string(files.size()) +
               " snapshots ignored (the server has a source a snapshot cannot hold); "
               "replaying the whole journal");
    return 0;
  }
  for (const std::string& path : files) {
    Result<std::vector<uint8_t>> bytes = ReadSnapshotFile(path);
    const Result<int64_t> covered =
        bytes.ok() ? node->RestoreSnapshot(*bytes, events) : Result<int64_t>(bytes.status());
    if (covered.ok()) {
      LogInfo("restored " + path + " (" + std::to_string(bytes->size()) + " bytes, " +
              std::to_string(*covered) + " of " + std::to_string(events.size()) +
              " journal events)");
      return *covered;
    }
    LogWarning(path + " refused: " + covered.status().message() +
               "; trying an older snapshot, else the whole journal");
  }
  return 0;
}

}  // namespace

// Logs the snapshot written off the loop once it is done (`wait`: also if it is not yet);
// true when none is in flight any more.
bool ServerJournal::CollectSnapshotWrite(bool wait) {
  if (!writing_.valid()) return true;
  if (!wait && writing_.wait_for(std::chrono::seconds(0)) != std::future_status::ready) {
    return false;
  }
  const Written written = writing_.get();
  if (written.status.ok()) {
    LogInfo(writing_what_ + ", written in " + std::to_string(1e3 * written.seconds) + " ms");
  } else {
    LogWarning("snapshot not written: " + written.status.message());
  }
  return true;
}

// Opens the journal in `dir`, restores the newest valid snapshot there, replays the journal
// after it through `node` (the same handlers, with the clocks they saw live) and has the
// node journal every input from now on.
Result<std::unique_ptr<ServerJournal>> ServerJournal::OpenAndReplay(const std::string& dir,
                                                                    bool defer_updates,
                                                                    ServerNode* node) {
  std::vector<LogEvent> events;
  Result<std::unique_ptr<Journal>> journal = Journal::Open(dir, &events);
  if (!journal.ok()) return journal.status();
  std::unique_ptr<ServerJournal> state(new ServerJournal);
  state->journal_ = std::move(*journal);
  state->dir_ = dir;
  state->node_ = node;
  const auto start = std::chrono::steady_clock::now();
  const std::clock_t cpu_start = std::clock();
  const int64_t covered = RestoreNewestSnapshot(dir, events, node);
  state->last_.events = static_cast<int64_t>(events.size());
  if (!events.empty()) {
    state->last_.last_utime = events.back().utime;
    state->last_.last_channel = events.back().channel;
  }
  state->snapshot_events_ = covered > 0 ? covered : -1;
  // Journaling from here: the replay journals no input, but the matches it has to run
  // again (not journaled before the crash) are, so a server killed during its replay
  // leaves them to the next one.
  ServerJournal* s = state.get();
  node->SetJournal(
      [s](const std::string& channel, int64_t clock_utime, const uint8_t* data, size_t size) {
        std::lock_guard<std::mutex> lock(s->append_mutex_);
        const Status status = s->journal_->Append(channel, clock_utime, data, size);
        if (status.ok()) s->last_ = {s->last_.events + 1, clock_utime, channel};
        return status;
      });
  const int64_t deferred_before = node->server().stats().deferred_updates;  // the snapshot's
  const ServerNode::JournalReplay replay =
      node->ReplayJournal(events, defer_updates, static_cast<size_t>(covered));
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const double cpu_seconds = static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC;
  std::ostringstream line;
  line << "journal " << state->journal_->path() << ": " << (covered > 0 ? "snapshot + " : "")
       << "replayed " << replay.events << " of " << events.size() << " events ("
       << state->journal_->bytes() << " bytes) in " << seconds << " s (" << cpu_seconds
       << " s CPU, ";
  if (replay.deferred) {
    line << node->server().stats().deferred_updates - deferred_before
         << " solver updates deferred to batch steps, "
         << "the last " << 1e3 * replay.batch_step.seconds << " ms";
  } else {
    line << "every solver update run"
         << (defer_updates ? " (a scan-matching source or the reduced graph's fold reads the "
                             "estimate)"
                           : "");
  }
  if (replay.matches_journaled > 0 || replay.matches_run > 0) {
    line << "; scan matches: " << replay.matches_reused << " reused from the journal, "
         << replay.matches_run << " run (" << replay.matches_mismatched
         << " journaled for another match) (" << replay.matches_other_options
         << " journaled under other options)";
  }
  if (replay.matches_other_options > 0) {
    LogWarning(std::to_string(replay.matches_other_options) +
               " journaled scan matches were computed under other matcher or source options "
               "(or by an older server that did not record them): matched again");
  }
  line << "); resuming with " << node->server().StatusLine();
  LogInfo(line.str());
  node->ResumeClocks(ServerNode::WallClock());
  return state;
}

// Writes a snapshot when one is due (ServerOptions::snapshot_every_*), between two events
// (from the loop's timer: the state is the journal prefix's).
void ServerJournal::SnapshotIfDue(const ServerOptions& options, ServerNode* node) {
  if (!CollectSnapshotWrite(/*wait=*/false)) return;  // the previous one is still going
  const auto due = [&] {
    const int64_t fresh = last_.events - std::max<int64_t>(snapshot_events_, 0);
    if (fresh <= 0 || !node->CanSnapshot()) return false;
    const double since =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - snapshot_time_).count();
    return (options.snapshot_every_events > 0 && fresh >= options.snapshot_every_events) ||
           (options.snapshot_every_s > 0 && since >= options.snapshot_every_s);
  };
  {
    std::lock_guard<std::mutex> lock(append_mutex_);
    if (!due()) return;
  }
  // The scan sources' matches in flight end first (their results journaled: the recorder
  // takes the lock below), so the snapshot holds them and the journal prefix it covers is
  // final: only this thread submits matches.
  node->server().match_pool().WaitIdle();
  std::lock_guard<std::mutex> lock(append_mutex_);
  if (!due()) return;
  const auto now = std::chrono::steady_clock::now();
  snapshot_time_ = now;  // also after a failure: retried at the next period, not at once
  // Encoded here, between two events (the state is the journal prefix's); written off the
  // loop. A write that fails leaves the previous snapshots (and the journal) in place.
  const std::clock_t cpu_start = std::clock();
  Result<std::vector<uint8_t>> bytes = node->EncodeSnapshot(last_);
  const double encode_cpu = static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC;
  if (!bytes.ok()) {
    LogWarning("snapshot not written: " + bytes.status().message());
    return;
  }
  snapshot_events_ = last_.events;
  writing_what_ = "snapshot of " + std::to_string(last_.events) +
                  " journal events: " + std::to_string(bytes->size()) + " bytes, encoded in " +
                  std::to_string(1e3 * encode_cpu) + " ms CPU on the loop";
  writing_ =
      std::async(std::launch::async, [dir = dir_, events = last_.events, data = std::move(*bytes)] {
        const auto start = std::chrono::steady_clock::now();
        Written written;
        written.status = WriteSnapshotFile(dir, events, data, /*keep=*/2);
        written.seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        return written;
      });
}

ServerJournal::~ServerJournal() {
  if (node_ != nullptr) node_->SetJournal(nullptr);
  CollectSnapshotWrite(/*wait=*/true);
}

std::string ServerJournal::StatusText() const {
  std::lock_guard<std::mutex> lock(append_mutex_);
  return "journal " + std::to_string(journal_->events()) + " events " +
         std::to_string(journal_->bytes()) + " bytes, snapshot at " +
         std::to_string(std::max<int64_t>(snapshot_events_, 0));
}

}  // namespace anchormap
