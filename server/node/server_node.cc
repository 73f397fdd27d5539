#include "server/node/server_node.h"

#include <chrono>
#include <tuple>

#include "common/bus/codec.h"
#include "common/bus/delivery_codec.h"
#include "common/bus/map_codec.h"
#include "common/util/log.h"
#include "server/byte_codec.h"
#include "server/recorded_match_codec.h"

namespace anchormap {

int64_t ServerNode::WallClock() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

ServerNode::ServerNode(const ServerOptions& options, Publish publish, Clock clock)
    : options_(options),
      publish_(std::move(publish)),
      clock_(std::move(clock)),
      server_(std::make_unique<MappingServer>(options.server)) {}

void ServerNode::RequireAuthentication(Authenticator authenticator) {
  authenticator_.emplace(std::move(authenticator));
}

bool ServerNode::OnMessage(const std::string& channel, const uint8_t* data, size_t size) {
  const bool keyframes = channel == options_.channels.keyframes;
  if (!keyframes && channel != options_.channels.encounters) return false;
  std::vector<uint8_t> opened;
  if (authenticator_) {
    Result<std::vector<uint8_t>> payload = authenticator_->Open(channel, data, size);
    if (!payload.ok()) {
      server_->CountRejection(payload.status(), channel);
      return true;
    }
    opened = std::move(*payload);
    data = opened.data();
    size = opened.size();
  }
  Dispatch(channel, data, size, /*replaying=*/false);
  return true;
}

void ServerNode::Dispatch(const std::string& channel, const uint8_t* data, size_t size,
                          bool replaying) {
  // The logic counts its own refusals; the node counts what does not decode.
  if (channel == options_.channels.keyframes) {
    Result<Keyframe> keyframe = DecodeKeyframe(data, size);
    if (!keyframe.ok()) {
      server_->CountRejection(keyframe.status(), channel);
    } else {
      OnKeyframe(std::move(*keyframe), channel, data, size, replaying);
    }
  } else {
    const Result<Encounter> encounter = DecodeEncounter(data, size);
    if (!encounter.ok()) {
      server_->CountRejection(encounter.status(), channel);
    } else {
      OnEncounter(*encounter, channel, data, size, replaying);
    }
  }
}

void ServerNode::SetJournal(JournalAppend append) {
  journal_ = std::move(append);
  if (!journal_) {
    server_->match_pool().SetRecorder(nullptr);
    return;
  }
  server_->match_pool().SetRecorder(
      [append = journal_, utime = journal_utime_](const RecordedMatch& match) {
        const std::vector<uint8_t> bytes = EncodeRecordedMatch(match);
        const Status status = append(kJournalMatch, utime->load(), bytes.data(), bytes.size());
        if (!status.ok()) {
          LogWarning("match " + std::to_string(match.ordinal) +
                     " not journaled (a restart will run it again): " + status.message());
        }
      });
}

bool ServerNode::Replay(const LogEvent& event) {
  // Used by ReplayJournal before the inputs (MatchPool::Preload); nothing to apply here.
  if (event.channel == kJournalMatch) return true;
  if (event.channel == kJournalTick) {
    server_->Tick(event.utime);
    int64_t released = -1;  // a journal older than the count: all that was due
    if (event.data.size() == sizeof released) {
      released = ByteReader(event.data.data(), event.data.size()).I64();
    }
    if (released < 0) {
      while (server_->ReleaseDue(64) > 0) {
      }
    } else {
      // As many as the live tick's budget let through (the same ones: the same state).
      for (int64_t i = 0; i < released && server_->ReleaseDue(1) > 0; ++i) {
      }
    }
    return true;
  }
  if (event.channel == kJournalResume) {
    server_->ResumeClocks(event.utime);
    return true;
  }
  if (event.channel != options_.channels.keyframes &&
      event.channel != options_.channels.encounters) {
    return false;
  }
  server_->SetClock(event.utime);
  Dispatch(event.channel, event.data.data(), event.data.size(), /*replaying=*/true);
  return true;
}

ServerNode::JournalReplay ServerNode::ReplayJournal(const std::vector<LogEvent>& events,
                                                    bool defer_updates, size_t first) {
  JournalReplay replay;
  // A restored snapshot left the server deferring, its graph unsolved: solved at the end of
  // a deferred replay, or now when every update is to run.
  if (!defer_updates && server_->deferring_updates()) {
    replay.batch_step = server_->EndDeferredUpdates();
  }
  replay.deferred = defer_updates && server_->BeginDeferredUpdates();
  // The match results journaled live: the sources' replayed jobs get them instead of running
  // (from the whole journal: a job may have been submitted before a snapshot's end).
  std::vector<RecordedMatch> recorded;
  int64_t undecodable = 0;
  for (const LogEvent& event : events) {
    if (event.channel != kJournalMatch) continue;
    Result<RecordedMatch> match = DecodeRecordedMatch(event.data.data(), event.data.size());
    if (match.ok()) {
      recorded.push_back(std::move(*match));
    } else {
      ++undecodable;
    }
  }
  if (undecodable > 0) {
    LogWarning(std::to_string(undecodable) + " journaled match results do not decode: run again");
  }
  replay.matches_journaled = static_cast<int64_t>(recorded.size());
  MatchPool& pool = server_->match_pool();
  const MatchPoolStats before = pool.stats();
  pool.Preload(recorded);
  for (size_t i = first; i < events.size(); ++i) {
    if (Replay(events[i])) ++replay.events;
  }
  if (replay.deferred) replay.batch_step = server_->EndDeferredUpdates();
  replay.matches_reused = pool.stats().reused - before.reused;
  replay.matches_run = pool.stats().submitted - before.submitted - replay.matches_reused;
  replay.matches_mismatched = pool.stats().mismatched - before.mismatched;
  replay.matches_other_options = pool.stats().other_options - before.other_options;
  return replay;
}

Result<std::vector<uint8_t>> ServerNode::EncodeSnapshot(const JournalPosition& position) const {
  SnapshotNodeState node;
  node.position = position;
  node.robots = robots_;
  node.trajectories = trajectories_;
  return SnapshotCodec::Encode(*server_, node);
}

Result<int64_t> ServerNode::RestoreSnapshot(const std::vector<uint8_t>& bytes,
                                            const std::vector<LogEvent>& journal) {
  const Result<JournalPosition> position = SnapshotCodec::ReadPosition(bytes.data(), bytes.size());
  if (!position.ok()) return position.status();
  const int64_t covered = position->events;
  if (covered > static_cast<int64_t>(journal.size())) {
    return Status::Error(ErrorCode::kInvalidArgument, "snapshot covers " + std::to_string(covered) +
                                                          " journal events, the journal holds " +
                                                          std::to_string(journal.size()));
  }
  if (covered > 0 && (journal[covered - 1].utime != position->last_utime ||
                      journal[covered - 1].channel != position->last_channel)) {
    return Status::Error(ErrorCode::kInvalidArgument,
                         "snapshot's last journal event (" + position->last_channel + " at " +
                             std::to_string(position->last_utime) +
                             ") is not the journal's event " + std::to_string(covered));
  }
  auto fresh = std::make_unique<MappingServer>(options_.server);
  SnapshotNodeState node;
  if (Status s = SnapshotCodec::Decode(bytes.data(), bytes.size(), fresh.get(), &node); !s.ok()) {
    return s;
  }
  server_ = std::move(fresh);
  if (journal_) SetJournal(journal_);  // the new server's match pool records too
  robots_ = std::move(node.robots);
  trajectories_ = std::move(node.trajectories);
  return covered;
}

void ServerNode::Tick(int64_t now_utime) {
  const auto changes = [this] {
    return std::make_tuple(server_->update_count(), server_->order_stats().released,
                           server_->order_stats().silences, server_->receipt().num_bridged_gaps(),
                           server_->table().num_bridged_gaps());
  };
  const auto before = changes();
  server_->Tick(now_utime);
  // Online the inputs go into the graph from here, within the release budget (the node's
  // clock), one at a time.
  const int64_t deadline = clock_() + static_cast<int64_t>(1e6 * options_.release_budget_s);
  int64_t released = 0;
  while (clock_() < deadline && server_->ReleaseDue(1) > 0) ++released;
  // A tick that changed anything (bridged gaps, silenced a trajectory, released inputs) is
  // replayed as a tick, with the number the budget let through: a replay that released all
  // that was due would release inputs the live server had not when the next input came,
  // and that input would be late in one and not in the other (a server behind its bus).
  if (journal_ && changes() != before) {
    ByteWriter count;
    count.I64(released);
    const Status status =
        journal_(kJournalTick, now_utime, count.bytes().data(), count.bytes().size());
    if (!status.ok()) server_->CountRejection(status, kJournalTick);
  }
}

void ServerNode::ResumeClocks(int64_t now_utime) {
  server_->ResumeClocks(now_utime);
  // Journaled, so that a later restart's replay resumes them at the same point.
  if (journal_) {
    const Status status = journal_(kJournalResume, now_utime, nullptr, 0);
    if (!status.ok()) server_->CountRejection(status, kJournalResume);
  }
}

bool ServerNode::Journaled(const std::string& channel, const uint8_t* data, size_t size) {
  if (!journal_) return true;
  journal_utime_->store(server_->clock_utime());
  const Status status = journal_(channel, server_->clock_utime(), data, size);
  if (!status.ok()) server_->CountRejection(status, channel);
  return status.ok();
}

Status ServerNode::CheckNotFuture(int64_t utime) const {
  const int64_t now = clock_();
  const int64_t allowed = static_cast<int64_t>(1e6 * options_.max_future_s);
  // Decoded times are at most CodecLimits::kMaxUtime, so the difference cannot overflow.
  if (utime - now > allowed) {
    return Status::Error(ErrorCode::kFromFuture, "data time " + std::to_string(utime) + " is " +
                                                     std::to_string((utime - now) / 1000000) +
                                                     " s ahead of the receive clock");
  }
  return Status::Ok();
}

Status ServerNode::CheckRobotCap(const std::string& robot) const {
  if (robots_.count(robot) == 0 && static_cast<int>(robots_.size()) >= options_.max_robots) {
    return Status::Error(
        ErrorCode::kCapReached,
        "robot " + robot + " past the cap of " + std::to_string(options_.max_robots) + " robots");
  }
  return Status::Ok();
}

Status ServerNode::CheckKeyframe(const Keyframe& keyframe) const {
  if (Status refused = CheckNotFuture(keyframe.utime); !refused.ok()) return refused;
  if (static_cast<int64_t>(keyframe.scan.ranges.size()) > options_.max_scan_ranges) {
    return Status::Error(ErrorCode::kCapReached,
                         std::to_string(keyframe.scan.ranges.size()) + " ranges (cap " +
                             std::to_string(options_.max_scan_ranges) + ")");
  }
  if (Status refused = CheckRobotCap(keyframe.robot); !refused.ok()) return refused;
  if (trajectories_.count(TrajectoryName{keyframe.robot, keyframe.trajectory_id}) == 0 &&
      static_cast<int>(trajectories_.size()) >= options_.max_trajectories) {
    return Status::Error(ErrorCode::kCapReached,
                         "trajectory " + std::to_string(keyframe.trajectory_id) + " of " +
                             keyframe.robot + " past the cap of " +
                             std::to_string(options_.max_trajectories) + " trajectories");
  }
  return Status::Ok();
}

void ServerNode::OnKeyframe(Keyframe keyframe, const std::string& channel, const uint8_t* data,
                            size_t size, bool replaying) {
  // Replayed inputs passed the checks when they were journaled: checked again (against
  // today's clock, or caps changed since) some could be refused although the agents were
  // told they arrived.
  if (!replaying) {
    if (Status refused = CheckKeyframe(keyframe); !refused.ok()) {
      server_->CountRejection(refused, channel);
      return;
    }
    if (!Journaled(channel, data, size)) return;
  }
  const TrajectoryName trajectory{keyframe.robot, keyframe.trajectory_id};
  if (server_->OnKeyframe(std::move(keyframe)).ok()) {
    robots_.insert(trajectory.robot);
    trajectories_.insert(trajectory);
  }
}

void ServerNode::OnEncounter(const Encounter& encounter, const std::string& channel,
                             const uint8_t* data, size_t size, bool replaying) {
  if (!replaying) {
    Status refused = CheckNotFuture(encounter.utime);
    if (refused.ok()) refused = CheckRobotCap(encounter.observer);
    if (refused.ok()) refused = CheckRobotCap(encounter.observed);
    if (!refused.ok()) {
      server_->CountRejection(refused, channel);
      return;
    }
    if (!Journaled(channel, data, size)) return;
  }
  (void)server_->OnEncounter(encounter);
}

void ServerNode::PublishMap(int64_t now_utime, bool full) {
  const MapChunker::Split split = server_->SplitMergedMap(now_utime, full);
  for (const MergedMapChunk& chunk : split.chunks) {
    publish_(options_.channels.map_chunks, EncodeMergedMapChunk(chunk));
  }
  publish_(options_.channels.map_header, EncodeMergedMapHeader(split.header));
  // The covariances at their own period (each is a solve through R's bottom rows), at once
  // when the anchored set changed, and with every full map.
  MapPublisher& publisher = server_->publisher();
  std::vector<TrajectoryId> anchors = server_->PublishedAnchors();
  if (publisher.AnchorCovariancesDue(now_utime, anchors, full)) {
    publish_(options_.channels.anchor_covariances,
             EncodeAnchorCovariances(server_->BuildAnchorCovariances()));
    publisher.MarkAnchorCovariancesPublished(now_utime, std::move(anchors));
  }
  ++published_maps_;
}

void ServerNode::PublishGrid(bool full, bool complete) {
  for (const GridTile& tile :
       full ? server_->BuildGridTiles(complete) : server_->BuildChangedGridTiles()) {
    publish_(options_.channels.grid_tiles, EncodeGridTile(tile));
  }
  ++published_grids_;
}

void ServerNode::PublishDue(int64_t now_utime) {
  MapPublisher& publisher = server_->publisher();
  const int64_t update = server_->update_count();
  if (publisher.MapDue(now_utime, update)) {
    PublishMap(now_utime, /*full=*/false);
    publisher.MarkMapPublished(now_utime, update);
    last_map_utime_ = now_utime;
  }
  if (publisher.GridDue(now_utime, update)) {
    const bool full = publisher.GridFullDue(now_utime);
    PublishGrid(full);
    publisher.MarkGridPublished(now_utime, update);
    if (full) publisher.MarkGridFullPublished(now_utime);
  }
}

void ServerNode::RepublishMapDue(int64_t now_utime, double period_s) {
  if (server_->update_count() == 0) return;  // nothing mapped yet
  if (last_map_utime_ > 0 && static_cast<double>(now_utime - last_map_utime_) < 1e6 * period_s) {
    return;
  }
  PublishMap(now_utime, /*full=*/true);
  last_map_utime_ = now_utime;
}

void ServerNode::PublishStatus() {
  ServerStatus status = server_->BuildStatus();
  status.instance_id = instance_id_;
  status.kernel_drops = kernel_drops_;
  publish_(options_.channels.status, EncodeServerStatus(status));
}

void ServerNode::PublishAcks() {
  for (const DeliveryAck& ack : server_->BuildAcks()) {
    publish_(options_.channels.acks, EncodeDeliveryAck(ack));
  }
}

void ServerNode::PublishResendRequests() {
  for (const ResendRequest& request : server_->BuildResendRequests()) {
    publish_(options_.channels.resend_requests, EncodeResendRequest(request));
  }
}

void ServerNode::PublishAll() {
  PublishMap(clock_(), /*full=*/true);
  PublishGrid(/*full=*/true, /*complete=*/true);
  PublishStatus();
}

ServerNode::JournalAppend AppendToMemory(std::vector<LogEvent>* journal, std::mutex* mutex) {
  return [journal, mutex](const std::string& channel, int64_t clock_utime, const uint8_t* data,
                          size_t size) {
    std::unique_lock<std::mutex> lock;
    if (mutex != nullptr) lock = std::unique_lock<std::mutex>(*mutex);
    LogEvent event;
    event.channel = channel;
    event.utime = clock_utime;
    event.data.assign(data, data + size);
    journal->push_back(std::move(event));
    return Status::Ok();
  };
}

}  // namespace anchormap
