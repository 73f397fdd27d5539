// anchormap-bench-journal-replay: what a restart of `anchormap-server --journal DIR` costs at
// the end of a long mission, with the solver's updates run one by one as they ran live and
// deferred to batch steps (ServerNode::ReplayJournal). The live session is simulated in
// one process: the agents' keyframes and encounters (anchormap-replay --inputs-output) are
// given to a ServerNode as the online main does (its clock at each input's log time, a
// timer tick every 100 ms, the journal kept in memory); then fresh nodes replay that
// journal both ways. Prints the replays' CPU times (medians of --repeat runs) and how far
// their final maps (after the end-of-session batch step) lie from the live session's.
// Snapshots (server/snapshot_codec.h): the live session writes one every
// --snapshot-every-events journal events (the server's default), each timed (encoding CPU;
// with --dir, the file's write + fsync + rename, wall) and sized; a restart then restores
// the newest and replays the journal's tail (deferred), also timed, and with --dir the
// journal is written to DIR and reading it back (Journal::Open, which a restart does first
// whatever the snapshot) is timed as well.
//
//   anchormap-replay --log SIM.lcmlog --output OUT.lcmlog --inputs-output AGENTS.lcmlog
//   anchormap-bench-journal-replay --log AGENTS.lcmlog [--repeat 3] [--dir EMPTY_DIR]

#include <sys/resource.h>

#include <algorithm>
#include <cstdio>
#include <mutex>
#include <string>
#include <vector>

#include <chrono>

#include "common/bus/channels.h"
#include "common/bus/journal.h"
#include "common/bus/lcm_log.h"
#include "common/util/log.h"
#include "common/util/options_loader.h"
#include "server/node/server_node.h"
#include "server/node/snapshot_store.h"
#include "tests/testing/map_difference.h"

namespace anchormap {
namespace {

double CpuSeconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
}

struct BenchOptions {
  std::string log;
  int repeat = 3;
  double convergence_step = 1e-12;  // the final batch steps iterate to the minimum
  int64_t snapshot_every_events = ServerOptions{}.snapshot_every_events;
  std::string dir;  // for the journal and snapshot files (empty: in memory only)
};

double WallSeconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

ServerOptions OnlineServerOptions(const BenchOptions& bench) {
  ServerOptions options;
  options.server.order.release_per_call = 0;  // as online: the timer's ticks release
  options.server.smoother.convergence_step = bench.convergence_step;
  return options;
}

void IgnoreOutputs(const std::string&, const std::vector<uint8_t>&) {}

struct ReplayFigures {
  double cpu_s = 0.0;
  double batch_step_ms = 0.0;
  double final_difference = 0.0;
};

double Median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  return values.empty() ? 0.0 : values[values.size() / 2];
}

int Run(const BenchOptions& bench) {
  LcmLogReader reader;
  if (Status s = reader.Open(bench.log); !s.ok()) return LogError(s.message()), 1;
  std::vector<LogEvent> inputs;
  while (auto event = reader.Next()) {
    if (event->channel == channels::kKeyframes || event->channel == channels::kEncounters) {
      inputs.push_back(std::move(*event));
    }
  }
  if (inputs.empty()) return LogError("no keyframes or encounters in " + bench.log), 1;

  // The live session, journaled.
  const ServerOptions options = OnlineServerOptions(bench);
  int64_t now = inputs.front().utime;
  std::vector<LogEvent> journal;
  std::mutex journal_mutex;  // scan-matching sources journal their matches from workers
  ServerNode live(options, IgnoreOutputs, [&now] { return now; });
  live.SetJournal(AppendToMemory(&journal, &journal_mutex));
  const int64_t tick = 100'000;
  int64_t next_tick = now + tick;
  // Snapshots as the online main writes them (between events, by journaled count).
  std::vector<uint8_t> snapshot;  // the newest
  int64_t snapshot_events = 0;
  std::vector<double> encode_ms, write_ms, sizes;
  double snapshot_cpu = 0.0;
  auto snapshot_if_due = [&] {
    const auto events = static_cast<int64_t>(journal.size());
    if (bench.snapshot_every_events <= 0 || events - snapshot_events < bench.snapshot_every_events)
      return;
    const double start = CpuSeconds();
    Result<std::vector<uint8_t>> bytes =
        live.EncodeSnapshot({events, journal.back().utime, journal.back().channel});
    const double encoded = CpuSeconds();
    if (!bytes.ok()) return (void)LogError(bytes.status().message());
    encode_ms.push_back(1e3 * (encoded - start));
    if (!bench.dir.empty()) {
      const double wall = WallSeconds();
      if (Status w = WriteSnapshotFile(bench.dir, events, *bytes, 2); !w.ok()) {
        LogError(w.message());
      }
      write_ms.push_back(1e3 * (WallSeconds() - wall));
    }
    snapshot_cpu += CpuSeconds() - start;
    sizes.push_back(static_cast<double>(bytes->size()));
    snapshot = std::move(*bytes);
    snapshot_events = events;
  };
  const double live_start = CpuSeconds();
  for (const LogEvent& event : inputs) {
    for (; next_tick <= event.utime; next_tick += tick) {
      now = next_tick;
      live.Tick(now);
      snapshot_if_due();
    }
    now = event.utime;
    live.server().SetClock(now);
    live.OnMessage(event.channel, event.data.data(), event.data.size());
    snapshot_if_due();
  }
  // The mission goes on a while after the last input: everything settles into the graph.
  for (int i = 0; i < 300; ++i) {
    now += tick;
    live.Tick(now);
  }
  const double live_cpu = CpuSeconds() - live_start - snapshot_cpu;
  live.server().Flush();
  const MergedMap live_map = live.server().BuildMergedMap();

  auto replay = [&](bool defer) {
    ServerNode restarted(options, IgnoreOutputs, [&now] { return now; });
    const double start = CpuSeconds();
    const ServerNode::JournalReplay result = restarted.ReplayJournal(journal, defer);
    ReplayFigures figures;
    figures.cpu_s = CpuSeconds() - start;
    figures.batch_step_ms = 1e3 * result.batch_step.seconds;
    restarted.server().Flush();
    figures.final_difference =
        testing::LargestPoseDifference(live_map, restarted.server().BuildMergedMap());
    return figures;
  };
  // A restart through the newest snapshot: restore, then the journal's tail, deferred.
  auto restore = [&]() -> ReplayFigures {
    ServerNode restarted(options, IgnoreOutputs, [&now] { return now; });
    ReplayFigures figures;
    const double start = CpuSeconds();
    std::vector<uint8_t> bytes = snapshot;
    if (!bench.dir.empty()) {  // as a restart does: from the file
      const std::vector<std::string> files = ListSnapshotFiles(bench.dir);
      Result<std::vector<uint8_t>> read =
          files.empty() ? Result<std::vector<uint8_t>>(Status::Error("no snapshot file"))
                        : ReadSnapshotFile(files.front());
      if (!read.ok()) return LogError(read.status().message()), figures;
      bytes = std::move(*read);
    }
    const Result<int64_t> covered = restarted.RestoreSnapshot(bytes, journal);
    if (!covered.ok()) return LogError(covered.status().message()), figures;
    const ServerNode::JournalReplay result =
        restarted.ReplayJournal(journal, true, static_cast<size_t>(*covered));
    figures.cpu_s = CpuSeconds() - start;
    figures.batch_step_ms = 1e3 * result.batch_step.seconds;
    restarted.server().Flush();
    figures.final_difference =
        testing::LargestPoseDifference(live_map, restarted.server().BuildMergedMap());
    return figures;
  };
  // Reading the journal back from its file (a restart's first step, whatever the snapshot).
  std::vector<double> read_cpu;
  if (!bench.dir.empty()) {
    {
      std::vector<LogEvent> existing;
      Result<std::unique_ptr<Journal>> file = Journal::Open(bench.dir, &existing);
      if (!file.ok()) return LogError(file.status().message()), 1;
      for (const LogEvent& e : journal) {
        if (Status a = (*file)->Append(e.channel, e.utime, e.data.data(), e.data.size()); !a.ok())
          return LogError(a.message()), 1;
      }
    }
    for (int r = 0; r < bench.repeat; ++r) {
      std::vector<LogEvent> existing;
      const double start = CpuSeconds();
      Result<std::unique_ptr<Journal>> file = Journal::Open(bench.dir, &existing);
      read_cpu.push_back(CpuSeconds() - start);
      if (!file.ok() || existing.size() != journal.size()) return LogError("journal read back"), 1;
    }
  }
  std::vector<double> full_cpu, deferred_cpu, batch_ms, snapshot_restart_cpu, snapshot_batch_ms;
  double full_difference = 0.0, deferred_difference = 0.0, snapshot_difference = 0.0;
  for (int r = 0; r < bench.repeat; ++r) {
    const ReplayFigures full = replay(false);
    const ReplayFigures deferred = replay(true);
    full_cpu.push_back(full.cpu_s);
    deferred_cpu.push_back(deferred.cpu_s);
    batch_ms.push_back(deferred.batch_step_ms);
    full_difference = std::max(full_difference, full.final_difference);
    deferred_difference = std::max(deferred_difference, deferred.final_difference);
    if (!snapshot.empty()) {
      const ReplayFigures restored = restore();
      snapshot_restart_cpu.push_back(restored.cpu_s);
      snapshot_batch_ms.push_back(restored.batch_step_ms);
      snapshot_difference = std::max(snapshot_difference, restored.final_difference);
    }
  }
  const MappingServer& server = live.server();
  std::printf(
      "journal: %zu events (%zu inputs) of %.1f s of data; live session: %lld keyframes, %lld "
      "encounters, %lld updates, %.3f s CPU\n",
      journal.size(), inputs.size(), 1e-6 * static_cast<double>(now - inputs.front().utime),
      static_cast<long long>(server.table().num_keyframes()),
      static_cast<long long>(server.stats().encounters_added),
      static_cast<long long>(server.stats().updates), live_cpu);
  std::printf("replay, every update run:         median %.3f s CPU of %d; final map vs live %.2e\n",
              Median(full_cpu), bench.repeat, full_difference);
  std::printf(
      "replay, updates deferred:         median %.3f s CPU of %d (closing batch step %.1f ms); "
      "final map vs live %.2e\n",
      Median(deferred_cpu), bench.repeat, Median(batch_ms), deferred_difference);
  std::printf("speed-up: %.1fx\n", Median(full_cpu) / std::max(1e-9, Median(deferred_cpu)));
  if (!snapshot.empty()) {
    std::printf(
        "snapshots: %zu written (every %lld events); size median %.0f bytes, last %.0f; "
        "encoding median %.1f ms CPU, last %.1f",
        sizes.size(), static_cast<long long>(bench.snapshot_every_events), Median(sizes),
        sizes.back(), Median(encode_ms), encode_ms.back());
    if (!write_ms.empty()) {
      std::printf("; file write+fsync+rename median %.1f ms wall, last %.1f", Median(write_ms),
                  write_ms.back());
    }
    std::printf("\n");
    std::printf(
        "restart from the newest snapshot (%lld events) + tail of %lld events, deferred: median "
        "%.3f s CPU of %d (closing batch step %.1f ms); final map vs live %.2e\n",
        static_cast<long long>(snapshot_events),
        static_cast<long long>(journal.size()) - static_cast<long long>(snapshot_events),
        Median(snapshot_restart_cpu), bench.repeat, Median(snapshot_batch_ms), snapshot_difference);
  }
  if (!read_cpu.empty()) {
    std::printf("reading the journal file back (Journal::Open): median %.3f s CPU of %d\n",
                Median(read_cpu), bench.repeat);
  }
  return 0;
}

int Main(int argc, char** argv) {
  BenchOptions bench;
  OptionsLoader loader("anchormap-bench-journal-replay", "--log AGENTS.lcmlog [--repeat N]",
                       "A restart's journal replay at the end of a mission: every solver update "
                       "run vs deferred to batch steps (CPU time, final map difference).");
  loader.Add("log", "log", &bench.log,
             "the agents' keyframes and encounters (anchormap-replay --inputs-output)", true);
  loader.Add("repeat", "repeat", &bench.repeat, "replays of each kind (the median is printed)");
  loader.Add("convergence_step", "convergence-step", &bench.convergence_step,
             "the batch steps' convergence step");
  loader.Add("snapshot_every_events", "snapshot-every-events", &bench.snapshot_every_events,
             "the live session's snapshot period in journal events (0 = none)");
  loader.Add("dir", "dir", &bench.dir,
             "an empty directory: the journal and snapshot files are written there and read "
             "back (timed); empty = in memory only");
  const ParseOutcome outcome = loader.Parse(argc, argv);
  if (!outcome.run) return outcome.exit_code;
  Status valid = bench.repeat >= 1 ? Status::Ok() : Status::Error("--repeat must be >= 1");
  if (valid.ok()) valid = loader.StartLogging("warning", "anchormap-bench-journal-replay");
  if (!valid.ok()) return loader.UsageError(valid);
  return Run(bench);
}

}  // namespace
}  // namespace anchormap

int main(int argc, char** argv) { return anchormap::Main(argc, argv); }
