// anchormap-server: the mapping server on the base station. Online: subscribes to every
// robot's keyframes and encounters over LCM and publishes the merged map, the anchors'
// covariances, the occupancy grid and its status. Offline (--log IN --output OUT): reads
// keyframes and encounters from an LCM log as fast as it can, writes the same outputs to
// another log (stamped with data time, so equal inputs give equal outputs) and exits.
// Online with --journal DIR: every input is journaled before it is applied, and a
// restarted server replays the journal first (crash recovery; common/bus/journal.h).

#include <chrono>
#include <csignal>
#include <ctime>
#include <iostream>
#include <random>
#include <sstream>

#include "common/bus/authenticator.h"
#include "common/bus/journal.h"
#include "common/bus/lcm_log.h"
#include "common/bus/lcm_loop.h"
#include "common/util/log.h"
#include "common/util/options_loader.h"
#include "common/util/retain_freed_memory.h"
#include "server/node/mapping_server_flags.h"
#include "server/node/server_journal.h"
#include "server/node/server_node.h"
#include "server/node/server_options.h"

namespace anchormap {
namespace {

volatile std::sig_atomic_t g_offline_stop = 0;
void OnOfflineSignal(int) { g_offline_stop = 1; }

int64_t WallUtime() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// A random positive 63-bit id for this process (its status messages tell restarts apart).
int64_t DrawInstanceId() {
  std::random_device device;
  const uint64_t bits = (static_cast<uint64_t>(device()) << 32) ^ device();
  const auto id = static_cast<int64_t>(bits >> 1);
  return id == 0 ? 1 : id;
}

// The node's own options: the bus, offline files, limits, channels, journal. The mapping
// server's options are registered by MappingServerFlags (shared with anchormap-replay).
void RegisterNodeOptions(OptionsLoader* l, ServerOptions* o) {
  AddLcmUrlOption(l, &o->lcm_url);
  l->Add("log", "log", &o->log_input, "offline: read keyframes/encounters from this LCM log");
  l->Add("output", "output", &o->log_output, "offline: write the outputs to this LCM log");
  l->Add("status_period_s", "status-period-s", &o->status_period_s,
         "status line and status message period (s; 0 = off)");
  l->Add("queue_capacity", "queue-capacity", &o->queue_capacity,
         "LCM receive queue per subscription, messages");
  l->Add("log_level", "log-level", &o->log_level, "debug, info, warning or error");
  l->Add("key_file", "key-file", &o->key_file,
         "authenticate: inputs must be signed under a key of this file, outputs are signed "
         "(empty: no authentication, with a warning)");
  l->Add("key_id", "key-id", &o->key_id,
         "the key that signs the outputs (empty: the file's first)");
  l->Add("max_robots", "max-robots", &o->max_robots, "robots admitted; later new ones are refused");
  l->Add("max_trajectories", "max-trajectories", &o->max_trajectories,
         "trajectories admitted; later new ones are refused");
  l->Add("max_scan_ranges", "max-scan-ranges", &o->max_scan_ranges,
         "keyframes whose scan has more ranges are refused");
  l->Add("max_future_s", "max-future-s", &o->max_future_s,
         "data times further ahead of the clock (wall time; offline: the log's) are refused (s)");
  l->Add("channels.keyframes", "keyframes-channel", &o->channels.keyframes, "keyframe_t input");
  l->Add("channels.encounters", "encounters-channel", &o->channels.encounters, "encounter_t input");
  l->Add("channels.map_header", "map-header-channel", &o->channels.map_header,
         "merged_map_header_t output (the merged map's header)");
  l->Add("channels.map_chunks", "map-chunks-channel", &o->channels.map_chunks,
         "merged_map_chunk_t output (the merged map's chunks)");
  l->Add("channels.anchor_covariances", "anchor-covariances-channel",
         &o->channels.anchor_covariances, "anchor_covariances_t output");
  l->Add("channels.grid_tiles", "grid-tiles-channel", &o->channels.grid_tiles,
         "grid_tile_t output");
  l->Add("channels.status", "status-channel", &o->channels.status, "server_status_t output");
  l->Add("channels.acks", "acks-channel", &o->channels.acks, "delivery_ack_t output (online)");
  l->Add("channels.resend_requests", "resend-requests-channel", &o->channels.resend_requests,
         "resend_request_t output (online)");
  l->Add("ack_period_s", "ack-period-s", &o->ack_period_s,
         "online: acknowledge every trajectory's keyframes / encounters this often (s)");
  l->Add("map_republish_period_s", "map-republish-period-s", &o->map_republish_period_s,
         "online: publish the merged map and anchor covariances again when none went out for "
         "this long (s; 0 = only after updates)");
  l->Add("journal_dir", "journal", &o->journal_dir,
         "online: write-ahead journal directory; an existing journal there is replayed at start "
         "(crash recovery)");
  l->Add("journal_defer_updates", "journal-defer-updates", &o->journal_defer_updates,
         "a restart's journal replay defers solver updates to batch steps (same graphs, the "
         "converged estimate; off by itself with scan-matching sources)");
  l->Add("snapshot_every_events", "snapshot-every-events", &o->snapshot_every_events,
         "with --journal: write a snapshot of the server's state after this many journaled "
         "events (0 = not by count); a restart replays only the journal after the newest");
  l->Add("snapshot_every_s", "snapshot-every-s", &o->snapshot_every_s,
         "with --journal: write a snapshot when this many seconds passed since the last and "
         "events were journaled (0 = not by time)");
  l->Add("release_budget_s", "release-budget-s", &o->release_budget_s,
         "online: wall time per 100 ms tick spent putting waiting inputs into the graph (s)");
}

// Loads the key file into `node` (with a warning when there is none).
Status SetUpAuthentication(const ServerOptions& options, ServerNode* node) {
  if (options.key_file.empty()) {
    LogWarning(
        "no --key-file: messages are not authenticated; anyone on the network can "
        "publish keyframes and encounters");
    return Status::Ok();
  }
  AuthenticatorOptions auth;
  auth.signing_key_id = options.key_id;
  auth.sender = "server";
  auth.first_counter = ServerNode::WallClock();
  Result<Authenticator> authenticator = LoadAuthenticator(options.key_file, auth);
  if (!authenticator.ok()) return authenticator.status();
  LogInfo("authentication on: the keys of " + options.key_file + ", signing with '" +
          authenticator->signing_key_id() + "'");
  node->RequireAuthentication(std::move(*authenticator));
  return Status::Ok();
}

int RunOnline(const ServerOptions& given) {
  // Message handlers only receive (delivery table, journal); the timer's ticks put inputs
  // into the graph, within --release-budget-s each.
  ServerOptions options = given;
  options.server.order.release_per_call = 0;
  Result<std::unique_ptr<LcmLoop>> created = LcmLoop::Create(options.lcm_url);
  if (!created.ok()) {
    LogError(created.status().message());
    return 1;
  }
  std::unique_ptr<LcmLoop> loop = std::move(*created);
  LcmLoop* bus = loop.get();
  ServerNode* node_pointer = nullptr;
  ServerNode node(
      options, [bus, &node_pointer](const std::string& channel, const std::vector<uint8_t>& bytes) {
        Authenticator* auth = node_pointer->authenticator();
        const Status status =
            bus->Publish(channel, auth ? auth->Seal(channel, bytes.data(), bytes.size()) : bytes);
        if (!status.ok()) LogWarning(status.message());
      });
  node_pointer = &node;
  node.set_instance_id(DrawInstanceId());
  if (Status s = SetUpAuthentication(options, &node); !s.ok()) {
    LogError(s.message());
    return 1;
  }
  std::unique_ptr<ServerJournal> journal;
  if (!options.journal_dir.empty()) {
    Result<std::unique_ptr<ServerJournal>> opened =
        ServerJournal::OpenAndReplay(options.journal_dir, options.journal_defer_updates, &node);
    if (!opened.ok()) {
      LogError(opened.status().message());
      return 1;
    }
    journal = std::move(*opened);
  }
  auto handler = [&node](const std::string& channel, const uint8_t* data, size_t size) {
    node.server().SetClock(WallUtime());
    node.OnMessage(channel, data, size);
    node.PublishDue(WallUtime());
  };
  for (const std::string& channel : {options.channels.keyframes, options.channels.encounters}) {
    const Status status = loop->Subscribe(channel, handler, options.queue_capacity);
    if (!status.ok()) {
      LogError(status.message());
      return 1;
    }
  }
  // Updates that arrived within a map period of the last publication go out from here;
  // gaps that waited too long are bridged; missing keyframes / encounters are asked for.
  loop->Every(std::chrono::milliseconds(100), [&node, &options, &journal] {
    node.Tick(WallUtime());
    if (journal) journal->SnapshotIfDue(options, &node);
    node.PublishResendRequests();
    node.PublishDue(WallUtime());
    if (options.map_republish_period_s > 0) {
      node.RepublishMapDue(WallUtime(), options.map_republish_period_s);
    }
  });
  loop->Every(std::chrono::milliseconds(static_cast<int64_t>(1e3 * options.ack_period_s)),
              [&node] { node.PublishAcks(); });
  auto status_line = [&node, bus, &journal] {
    bus->RefreshKernelDrops();
    const LcmLoopStats& s = bus->stats();
    node.set_kernel_drops(s.kernel_drops);
    std::string line = node.server().StatusLine() + " | lcm messages " +
                       std::to_string(s.messages_handled) + " max burst " +
                       std::to_string(s.max_burst) + " kernel drops " +
                       std::to_string(s.kernel_drops);
    if (journal) {
      line += " | " + journal->StatusText();
    }
    return line;
  };
  if (options.status_period_s > 0) {
    loop->Every(std::chrono::milliseconds(static_cast<int64_t>(1e3 * options.status_period_s)),
                [&node, status_line] {
                  LogInfo(status_line());
                  node.PublishStatus();
                });
  }
  loop->StopOnSignals(
      [](int number) { LogInfo("signal " + std::to_string(number) + ": stopping"); });
  LogInfo("instance " + std::to_string(node.instance_id()) + " listening on " +
          options.channels.keyframes + " and " + options.channels.encounters + " (" +
          (options.lcm_url.empty() ? std::string("default LCM URL") : options.lcm_url) + ")");
  // A restarted server says so at once (its new instance id), with what the journal gave it.
  node.PublishStatus();
  loop->Run();
  if (journal) journal->WaitForSnapshotWrite();
  // What is solved goes out first: the sources' last look below waits for their queued
  // matches, which on a starved machine can outlast the caller's patience, and a second
  // signal now ends the process with this map already published.
  loop->RestoreDefaultSignals();
  node.server().SolvePending();
  node.PublishAll();
  LogInfo("published the solved map; admitting what still waits (a second signal ends now)");
  // End of the session: what still waits is admitted (gaps bridged), then one batch step,
  // and the converged map goes out.
  node.server().Flush();
  const std::string final_line = status_line();  // (also refreshes the drop count)
  node.PublishAll();
  LogInfo("final: " + final_line);
  return 0;
}

int RunOffline(const ServerOptions& options) {
  LcmLogReader reader;
  if (Status s = reader.Open(options.log_input); !s.ok()) {
    LogError(s.message());
    return 1;
  }
  LcmLogWriter writer;
  if (Status s = writer.Open(options.log_output); !s.ok()) {
    LogError(s.message());
    return 1;
  }
  std::signal(SIGINT, OnOfflineSignal);
  std::signal(SIGTERM, OnOfflineSignal);
  ServerNode* node_pointer = nullptr;
  int64_t write_failures = 0;
  // The receive clock of a replay is the log's own: deterministic, and a keyframe dated
  // far beyond its event's time stamp is refused as it would have been live.
  int64_t event_utime = 0;
  ServerNode node(
      options,
      [&](const std::string& channel, const std::vector<uint8_t>& bytes) {
        if (!writer
                 .WriteRaw(channel, node_pointer->server().data_utime(), bytes.data(), bytes.size())
                 .ok()) {
          ++write_failures;
        }
      },
      [&event_utime] { return event_utime; });
  node_pointer = &node;
  if (Status s = SetUpAuthentication(options, &node); !s.ok()) {
    LogError(s.message());
    return 1;
  }
  const auto start = std::chrono::steady_clock::now();
  int64_t events = 0, used = 0, next_status_utime = 0;
  while (!g_offline_stop) {
    const std::optional<LogEvent> event = reader.Next();
    if (!event) break;
    ++events;
    event_utime = event->utime;
    if (!node.OnMessage(event->channel, event->data.data(), event->data.size())) continue;
    ++used;
    const int64_t now = node.server().data_utime();
    node.PublishDue(now);
    if (options.status_period_s > 0 && now >= next_status_utime) {
      if (next_status_utime > 0) {
        LogInfo(node.server().StatusLine());
        node.PublishStatus();
      }
      next_status_utime = now + static_cast<int64_t>(1e6 * options.status_period_s);
    }
  }
  if (g_offline_stop) LogWarning("interrupted: writing the outputs of what was read so far");
  if (used == 0) {
    LogWarning("no " + options.channels.keyframes + " / " + options.channels.encounters +
               " messages in " + options.log_input +
               " (a raw-sensor log? anchormap-replay runs the agents too)");
  }
  node.server().Flush();
  node.PublishAll();
  writer.Close();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  LogInfo("final: " + node.server().StatusLine());
  std::ostringstream summary;
  summary << "read " << events << " events (" << used << " keyframes/encounters) in " << seconds
          << " s; wrote " << node.published_maps() << " maps, " << node.published_grids()
          << " grids to " << options.log_output;
  LogInfo(summary.str());
  if (write_failures > 0) {
    LogError(std::to_string(write_failures) + " writes to " + options.log_output + " failed");
    return 1;
  }
  if (!reader.problems().empty()) {
    for (const std::string& problem : reader.problems()) {
      LogError(options.log_input + ": " + problem);
    }
    LogError(options.log_input + " is corrupt: " + std::to_string(reader.problems().size()) +
             " damaged stretch(es) skipped; the outputs hold the " + std::to_string(events) +
             " events that were sound");
    return 3;
  }
  return 0;
}

int Main(int argc, char** argv) {
  ServerOptions options = DaemonDefaults();
  // --log reads what a bus carried (a recording, a journal): settled in data time, so its
  // map is the live server's (online the wall clock settles).
  options.server.order.settle_offline = true;
  OptionsLoader loader(
      "anchormap-server",
      "[--lcm-url URL] [--config FILE] [options]\n   or: anchormap-server --log IN.lcmlog --output "
      "OUT.lcmlog [options]",
      "The anchormap mapping server: merges every robot's keyframes into one map with anchor\n"
      "nodes (one pose graph per trajectory, joined at encounters) and publishes it over LCM.");
  RegisterNodeOptions(&loader, &options);
  const MappingServerFlags server_flags(&loader, &options.server);
  const ParseOutcome outcome = loader.Parse(argc, argv);
  if (!outcome.run) return outcome.exit_code;
  Status valid = server_flags.Apply();
  if (valid.ok()) valid = options.Validate();
  if (valid.ok()) valid = loader.StartLogging(options.log_level, "anchormap-server");
  if (!valid.ok()) return loader.UsageError(valid);
  return options.log_input.empty() ? RunOnline(options) : RunOffline(options);
}

}  // namespace
}  // namespace anchormap

int main(int argc, char** argv) {
  anchormap::RetainFreedMemory();
  return anchormap::Main(argc, argv);
}
