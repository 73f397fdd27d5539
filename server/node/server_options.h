#pragma once
// Options of anchormap-server: one source of defaults. The flags, config keys, --help and
// the table in docs/DAEMONS.md come from the registration in server_main.cc.

#include <optional>
#include <string>

#include "common/bus/channels.h"
#include "common/util/status.h"
#include "server/mapping_server.h"

namespace anchormap {

struct ServerChannels {
  std::string keyframes = channels::kKeyframes;
  std::string encounters = channels::kEncounters;
  std::string map_header = channels::kMapHeader;
  std::string map_chunks = channels::kMapChunks;
  std::string anchor_covariances = channels::kAnchorCovariances;
  std::string grid_tiles = channels::kGridTiles;
  std::string status = channels::kServerStatus;
  std::string acks = channels::kAcks;
  std::string resend_requests = channels::kResendRequests;
};

struct ServerOptions {
  std::string lcm_url;  // empty: LCM's default ($LCM_DEFAULT_URL or the udpm default)
  // Offline: read keyframes and encounters from this LCM log as fast as possible and
  // write the outputs to log_output (both or neither).
  std::string log_input;
  std::string log_output;
  // Status line and status message period (0 = off). Offline: in data time.
  double status_period_s = 5.0;
  // Receive queue per subscription (LCM's default of 30 drops bursts silently).
  int queue_capacity = 10000;
  // Online: cumulative acknowledgements of every trajectory this often (s).
  double ack_period_s = 0.5;
  // Online: the merged map (every chunk) and anchor covariances are published again when
  // none went out for this long (s; 0 = only after updates), so one lost datagram does not
  // leave subscribers with a stale map.
  double map_republish_period_s = 5.0;
  // Online: each 100 ms tick puts waiting inputs into the graph for at most this long (wall
  // time); message handlers only receive, so the loop keeps reading resends and acks while
  // the scan matching works through a backlog.
  double release_budget_s = 0.08;
  // Online crash recovery: the write-ahead journal's directory (empty = none). At start the
  // journal found there is replayed (same graphs and estimate), then the server goes live.
  std::string journal_dir;
  // The restart's replay defers the solver's updates to batch steps (ServerNode::
  // ReplayJournal; automatically off when a scan-matching source is on). false: every
  // update runs as it did live (slower; for comparison).
  bool journal_defer_updates = true;
  // Periodic snapshots with --journal (server/node/snapshot_store.h): one is written when
  // this many events were journaled since the last, or this many seconds passed and some
  // were (0 switches a rule off; both 0: no snapshots). A restart restores the newest valid
  // one and replays only the journal after it; with the scan-matching sources on too (their
  // state and the smoother's are in a snapshot: server/snapshot_codec.h).
  int64_t snapshot_every_events = 5000;
  double snapshot_every_s = 300.0;
  std::string log_level = "info";
  // Authentication (common/bus/authenticator.h): with a key file, keyframes and encounters
  // must come in anchormap.signed_t envelopes under one of its keys, and what the server
  // publishes goes out in envelopes under key_id (empty: the file's first key).
  std::string key_file;
  std::string key_id;
  // Hostile input: new robots and trajectories past these caps are refused (memory stays
  // bounded whatever is published), as are scans of more ranges than max_scan_ranges.
  int max_robots = 256;  // the scale benchmark runs 100 robots
  int max_trajectories = 1024;
  int max_scan_ranges = 8192;
  // Data times further than this ahead of the server's clock (wall time online, the log's
  // own time stamps offline) are refused, so that a message dated 2100 cannot move the
  // data clock.
  double max_future_s = 30.0;
  MappingServerOptions server;
  ServerChannels channels;

  Status Validate() const {
    if (log_input.empty() != log_output.empty())
      return Status::Error("--log and --output go together");
    if (!log_input.empty() && log_input == log_output)
      return Status::Error("--output must differ from --log");
    if (!(status_period_s >= 0)) return Status::Error("status_period_s must be >= 0");
    if (!(ack_period_s > 0)) return Status::Error("ack_period_s must be > 0");
    if (!(map_republish_period_s >= 0)) return Status::Error("map_republish_period_s must be >= 0");
    if (!(release_budget_s > 0)) return Status::Error("release_budget_s must be > 0");
    if (!journal_dir.empty() && !log_input.empty())
      return Status::Error("--journal is for the online server (not with --log)");
    if (snapshot_every_events < 0) return Status::Error("snapshot_every_events must be >= 0");
    if (!(snapshot_every_s >= 0)) return Status::Error("snapshot_every_s must be >= 0");
    if (queue_capacity < 30) return Status::Error("queue_capacity must be >= 30");
    if (max_robots < 1) return Status::Error("max_robots must be >= 1");
    if (max_trajectories < 1) return Status::Error("max_trajectories must be >= 1");
    if (max_scan_ranges < 1) return Status::Error("max_scan_ranges must be >= 1");
    if (!(max_future_s >= 0)) return Status::Error("max_future_s must be >= 0");
    if (!key_id.empty() && key_file.empty()) return Status::Error("--key-id needs --key-file");
    return server.Validate();
  }
};

// The daemons' defaults: anchormap-server (online and --log) and anchormap-replay both start
// from these, so the two cannot drift apart. Both scan-matching sources are on (issue 11: the
// demo's merged map is 10x more accurate with them), and the reduced pose graph (issue 12).
// ServerOptions{} and MappingServerOptions{} keep them off, so that unit tests and library
// users switch them on where they mean to.
inline ServerOptions DaemonDefaults() {
  ServerOptions options;
  options.server.loop_closures = true;
  options.server.scan_encounters = true;
  // 100 robots send ~150 keyframes per second of data: one solver update per input was
  // most of the server's CPU (docs/ARCHITECTURE.md, "Server cost at scale").
  options.server.solve_period_s = 0.5;
  // A keyframe in a mapped place folds onto its node: the graph grows with the area, not with
  // time; the 30-minute run's update cost stays flat and every 100 x 180 seed's merged map is
  // more accurate (docs/ARCHITECTURE.md, "Bounding the graph by area"; --reduced-graph false
  // keeps every keyframe a variable).
  options.server.reduced_graph.enabled = true;
  return options;
}

}  // namespace anchormap
