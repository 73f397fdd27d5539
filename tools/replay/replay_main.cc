// anchormap-replay: runs one anchormap-agent per robot and anchormap-server in ONE process
// over an in-process bus (InProcessBus: memq://'s delivery order without its pipe), fed from a
// raw-sensor LCM log (anchormap-sim, anchormap-import-carmen), and writes the server's outputs
// to another log. The same code paths as the daemons (AgentNode, ServerNode, the codec),
// deterministic and as fast as the CPU allows: for demos, evaluation runs, and the multi-process
// test's fallback where network namespaces are unavailable. Times are data times (the input log's
// utimes).

#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <set>
#include <sstream>

#include <sys/resource.h>
#include <sys/time.h>
#include <time.h>

#include "agent/node/agent_node.h"
#include "common/bus/channels.h"
#include "common/bus/lcm_log.h"
#include "common/util/log.h"
#include "common/util/options_loader.h"
#include "common/util/retain_freed_memory.h"
#include "server/node/mapping_server_flags.h"
#include "server/node/server_node.h"
#include "tools/replay/in_process_bus.h"

namespace anchormap {
namespace {

struct ReplayOptions {
  std::string input;
  std::string output;
  std::string robots;  // comma-separated; empty: every <R>_ODOMETRY channel in the input
  double max_range_m = 30.0;
  double keyframe_distance_m = 0.5;
  double keyframe_angle_rad = 0.35;
  bool scan_matching = true;
  std::string log_level = "info";
  std::string update_times;  // CSV of every solver update's cost (benchmarks)
  // The server's status and work lines (info) every this many seconds of data (0: none).
  double status_period_s = 0.0;
  // The agents' keyframes and encounters, as a logger on the bus would record them (the
  // input of anchormap-server --log and tools/bench's journal replay benchmark).
  std::string inputs_output;
  // The daemon's defaults (scan-matching sources on; offline their decisions depend only on
  // the input set: the canonical order, worker results used at fixed points).
  ServerOptions server = DaemonDefaults();
};

// One line per solver update: data time (s since the first), its cost (wall ms), batch step
// or not, the process's CPU seconds when the line was written, and the update's CPU ms (the
// server thread's: on a loaded machine the wall time also counts waiting for a core). Written as
// the replay goes (every few thousand events), so that a long benchmark stopped early still leaves
// its curve.
double CpuSeconds(clockid_t clock) {
  timespec t{};
  clock_gettime(clock, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}
double ProcessCpuSeconds() { return CpuSeconds(CLOCK_PROCESS_CPUTIME_ID); }
double ThreadCpuSeconds() { return CpuSeconds(CLOCK_THREAD_CPUTIME_ID); }

class UpdateTimesWriter {
 public:
  Status Open(const std::string& path) {
    path_ = path;
    out_.open(path);
    if (!out_) return Status::Error(ErrorCode::kIoError, "cannot write " + path);
    out_ << "data_s,update_ms,batch_step,cpu_s,update_cpu_ms\n";
    return Flush();
  }
  // Writes the updates after those already written.
  Status Append(const std::vector<UpdateTiming>& times) {
    if (written_ == 0 && !times.empty()) start_ = times.front().data_utime;
    const double cpu = ProcessCpuSeconds();
    for (; written_ < times.size(); ++written_) {
      const UpdateTiming& t = times[written_];
      out_ << 1e-6 * static_cast<double>(t.data_utime - start_) << ',' << t.ms << ','
           << (t.batch_step ? 1 : 0) << ',' << cpu << ',' << t.cpu_ms << '\n';
    }
    return Flush();
  }

 private:
  static double ProcessCpuSeconds() {
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    const auto seconds = [](const timeval& t) {
      return static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_usec);
    };
    return seconds(usage.ru_utime) + seconds(usage.ru_stime);
  }
  Status Flush() {
    out_.flush();
    return out_ ? Status::Ok() : Status::Error(ErrorCode::kIoError, "cannot write " + path_);
  }

  std::string path_;
  std::ofstream out_;
  size_t written_ = 0;
  int64_t start_ = 0;
};

std::set<std::string> RobotsInLog(const std::string& path) {
  std::set<std::string> robots;
  LcmLogReader reader;
  if (!reader.Open(path).ok()) return robots;
  const std::string suffix = channels::kOdometrySuffix;
  while (auto event = reader.Next()) {
    const std::string& c = event->channel;
    if (c.size() > suffix.size() &&
        c.compare(c.size() - suffix.size(), suffix.size(), suffix) == 0) {
      robots.insert(c.substr(0, c.size() - suffix.size()));
    }
  }
  return robots;
}

int Run(const ReplayOptions& options) {
  std::set<std::string> robots;
  if (options.robots.empty()) {
    robots = RobotsInLog(options.input);
  } else {
    std::stringstream list(options.robots);
    for (std::string robot; std::getline(list, robot, ',');) {
      if (!robot.empty()) robots.insert(robot);
    }
  }
  if (robots.empty()) {
    LogError("no robots: no <ROBOT>_ODOMETRY channel in " + options.input + " and no --robots");
    return 1;
  }
  LcmLogReader reader;
  LcmLogWriter writer;
  if (Status s = reader.Open(options.input); !s.ok()) return LogError(s.message()), 1;
  if (Status s = writer.Open(options.output); !s.ok()) return LogError(s.message()), 1;
  InProcessBus bus;
  LcmLogWriter inputs_writer;
  if (!options.inputs_output.empty()) {
    if (Status s = inputs_writer.Open(options.inputs_output); !s.ok()) {
      return LogError(s.message()), 1;
    }
  }
  int64_t event_utime = 0;  // the input log's time of the event being replayed
  int64_t inputs_write_failures = 0;

  auto publish = [&bus](const std::string& channel, const std::vector<uint8_t>& bytes) {
    bus.Publish(channel, bytes);
  };
  std::vector<std::unique_ptr<AgentNode>> agents;
  int64_t trajectory_id = 1;
  for (const std::string& robot : robots) {
    AgentNodeOptions agent_options;
    agent_options.agent.robot = robot;
    agent_options.agent.trajectory_id = trajectory_id++;  // deterministic ids
    agent_options.reliable = false;  // the in-process bus loses nothing; no acknowledgements
    agent_options.agent.max_range_m = options.max_range_m;
    agent_options.agent.keyframer.max_distance_m = options.keyframe_distance_m;
    agent_options.agent.keyframer.max_angle_rad = options.keyframe_angle_rad;
    agent_options.agent.scan_matching.enabled = options.scan_matching;
    if (Status valid = agent_options.Validate(); !valid.ok()) return LogError(valid.message()), 2;
    agents.push_back(std::make_unique<AgentNode>(agent_options, publish));
    AgentNode* agent = agents.back().get();
    for (const std::string& channel : agent->InputChannels()) {
      bus.Subscribe(channel, [agent](const std::string& c, const uint8_t* d, size_t n) {
        agent->OnMessage(c, d, n);
      });
    }
  }
  ServerNode* server_pointer = nullptr;
  ServerNode server(options.server,
                    [&](const std::string& channel, const std::vector<uint8_t>& bytes) {
                      (void)writer.WriteRaw(channel, server_pointer->server().data_utime(),
                                            bytes.data(), bytes.size());
                    });
  server_pointer = &server;
  for (const std::string& channel :
       {options.server.channels.keyframes, options.server.channels.encounters}) {
    bus.Subscribe(channel, [&](const std::string& c, const uint8_t* d, size_t n) {
      if (!options.inputs_output.empty() && !inputs_writer.WriteRaw(c, event_utime, d, n).ok()) {
        ++inputs_write_failures;
      }
      server.OnMessage(c, d, n);
      server.PublishDue(server.server().data_utime());
    });
  }
  UpdateTimesWriter update_times;
  if (!options.update_times.empty()) {
    if (Status s = update_times.Open(options.update_times); !s.ok()) {
      return LogError(s.message()), 1;
    }
  }
  constexpr int64_t kUpdateTimesEveryEvents = 5000;
  int64_t events = 0;
  int64_t first_utime = -1, next_status_utime = 0;
  while (auto event = reader.Next()) {
    ++events;
    event_utime = event->utime;
    bus.Publish(event->channel, std::move(event->data));
    bus.HandlePending();
    if (first_utime < 0) first_utime = event_utime;
    if (options.status_period_s > 0 && event_utime - first_utime >= next_status_utime) {
      if (next_status_utime > 0) {
        LogInfo("status at " + std::to_string(next_status_utime / 1000000) +
                " s of data: " + server.server().StatusLine() + " | " + server.server().WorkLine() +
                " | process cpu s " + std::to_string(ProcessCpuSeconds()) + " main thread " +
                std::to_string(ThreadCpuSeconds()));
      }
      next_status_utime += static_cast<int64_t>(1e6 * options.status_period_s);
    }
    if (!options.update_times.empty() && events % kUpdateTimesEveryEvents == 0) {
      (void)update_times.Append(server.server().update_times());  // checked at the end
    }
  }
  server.server().Flush();
  server.PublishAll();
  writer.Close();
  if (!options.inputs_output.empty()) {
    inputs_writer.Close();
    if (inputs_write_failures > 0) {
      LogError(std::to_string(inputs_write_failures) + " writes to " + options.inputs_output +
               " failed");
      return 1;
    }
  }
  if (!options.update_times.empty()) {
    if (Status written = update_times.Append(server.server().update_times()); !written.ok()) {
      LogError(written.message());
      return 1;
    }
  }
  for (const auto& agent : agents) LogInfo(agent->StatusLine());
  LogInfo("server: " + server.server().StatusLine());
  LogInfo("server work: " + server.server().WorkLine());
  LogInfo("replayed " + std::to_string(events) + " events; wrote " +
          std::to_string(server.published_maps()) + " maps to " + options.output);
  return 0;
}

int Main(int argc, char** argv) {
  ReplayOptions options;
  OptionsLoader loader(
      "anchormap-replay", "--log SIM.lcmlog --output OUT.lcmlog [--robots R1,R2]",
      "Agents and server in one process over an in-process bus, fed from a raw-sensor log.");
  loader.Add("log", "log", &options.input, "raw-sensor LCM log to replay", true);
  loader.Add("output", "output", &options.output, "LCM log for the server's outputs", true);
  loader.Add("robots", "robots", &options.robots,
             "robots to run agents for (empty: all in the log)");
  loader.Add("max_range_m", "max-range-m", &options.max_range_m, "agents' laser max range (m)");
  loader.Add("keyframe_distance_m", "keyframe-distance-m", &options.keyframe_distance_m,
             "agents' keyframe distance (m)");
  loader.Add("keyframe_angle_rad", "keyframe-angle-rad", &options.keyframe_angle_rad,
             "agents' keyframe angle (rad)");
  loader.Add("scan_matching", "scan-matching", &options.scan_matching,
             "agents refine odometry by scan matching (false: raw odometry)");
  loader.Add("update_times", "update-times", &options.update_times,
             "write every solver update's data time, cost (ms), kind and the process's CPU "
             "seconds to this CSV, as the replay goes (empty: none; "
             "tools/bench/scale_figures.sh reads it)");
  loader.Add("inputs_output", "inputs-output", &options.inputs_output,
             "also write the agents' keyframes and encounters to this LCM log (empty: none)");
  loader.Add("status_period_s", "status-period-s", &options.status_period_s,
             "log the server's status and work counters every this many seconds of data "
             "(info; 0: only at the end)");
  const MappingServerFlags server_flags(&loader, &options.server.server, "server: ");
  loader.Add("log_level", "log-level", &options.log_level, "debug, info, warning or error");
  const ParseOutcome outcome = loader.Parse(argc, argv);
  if (!outcome.run) return outcome.exit_code;
  options.server.server.record_update_times = !options.update_times.empty();
  Status valid = server_flags.Apply();
  if (valid.ok()) valid = options.server.Validate();
  if (valid.ok() && options.input == options.output) {
    valid = Status::Error("--output must differ from --log");
  }
  if (valid.ok()) valid = loader.StartLogging(options.log_level, "anchormap-replay");
  if (!valid.ok()) return loader.UsageError(valid);
  return Run(options);
}

}  // namespace
}  // namespace anchormap

int main(int argc, char** argv) {
  anchormap::RetainFreedMemory();
  return anchormap::Main(argc, argv);
}
