// anchormap-bench-journal-replay: what a restart of `anchormap-server --journal DIR` costs at
// the end of a long mission, with the solver's updates run one by one as they ran live and
// deferred to batch steps (ServerNode::ReplayJournal). The live session is simulated in
// one process: the agents' keyframes and encounters (anchormap-replay --inputs-output) are
// given to a ServerNode as the online main does (its clock at each input's log time, a
// timer tick every 100 ms, the journal kept in memory); then fresh nodes replay that
// journal both ways. Prints the replays' CPU times (medians of --repeat runs) and how far
// their final maps (after the end-of-session batch step) lie from the live session's.
//
//   anchormap-replay --log SIM.lcmlog --output OUT.lcmlog --inputs-output AGENTS.lcmlog
//   anchormap-bench-journal-replay --log AGENTS.lcmlog [--repeat 3]

#include <sys/resource.h>

#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

#include "common/bus/channels.h"
#include "common/bus/lcm_log.h"
#include "common/util/log.h"
#include "common/util/options_loader.h"
#include "server/node/server_node.h"

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
};

ServerOptions OnlineServerOptions(const BenchOptions& bench) {
  ServerOptions options;
  options.server.order.release_per_call = 0;  // as online: the timer's ticks release
  options.server.smoother.convergence_step = bench.convergence_step;
  return options;
}

void IgnoreOutputs(const std::string&, const std::vector<uint8_t>&) {}

// The largest difference between two maps' poses (infinite when their shapes differ).
double MaxPoseDifference(const MergedMap& a, const MergedMap& b) {
  if (a.trajectories.size() != b.trajectories.size() || a.encounters.size() != b.encounters.size())
    return 1e300;
  double largest = 0.0;
  for (size_t t = 0; t < a.trajectories.size(); ++t) {
    const auto& x = a.trajectories[t].poses;
    const auto& y = b.trajectories[t].poses;
    if (x.size() != y.size()) return 1e300;
    for (size_t i = 0; i < x.size(); ++i) {
      largest = std::max(largest, PoseError(x[i], y[i]).cwiseAbs().maxCoeff());
    }
  }
  return largest;
}

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
  ServerNode live(options, IgnoreOutputs, [&now] { return now; });
  live.SetJournal([&journal](const std::string& channel, int64_t clock_utime, const uint8_t* data,
                             size_t size) {
    LogEvent event;
    event.channel = channel;
    event.utime = clock_utime;
    event.data.assign(data, data + size);
    journal.push_back(std::move(event));
    return Status::Ok();
  });
  const int64_t tick = 100'000;
  int64_t next_tick = now + tick;
  const double live_start = CpuSeconds();
  for (const LogEvent& event : inputs) {
    for (; next_tick <= event.utime; next_tick += tick) {
      now = next_tick;
      live.Tick(now);
    }
    now = event.utime;
    live.server().SetClock(now);
    live.OnMessage(event.channel, event.data.data(), event.data.size());
  }
  // The mission goes on a while after the last input: everything settles into the graph.
  for (int i = 0; i < 300; ++i) {
    now += tick;
    live.Tick(now);
  }
  const double live_cpu = CpuSeconds() - live_start;
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
    figures.final_difference = MaxPoseDifference(live_map, restarted.server().BuildMergedMap());
    return figures;
  };
  std::vector<double> full_cpu, deferred_cpu, batch_ms;
  double full_difference = 0.0, deferred_difference = 0.0;
  for (int r = 0; r < bench.repeat; ++r) {
    const ReplayFigures full = replay(false);
    const ReplayFigures deferred = replay(true);
    full_cpu.push_back(full.cpu_s);
    deferred_cpu.push_back(deferred.cpu_s);
    batch_ms.push_back(deferred.batch_step_ms);
    full_difference = std::max(full_difference, full.final_difference);
    deferred_difference = std::max(deferred_difference, deferred.final_difference);
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
