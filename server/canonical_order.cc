#include "server/canonical_order.h"

#include <algorithm>
#include <utility>

namespace anchormap {

void CanonicalInputOrder::AddKeyframe(TrajectoryId stream_id, Keyframe keyframe,
                                      int64_t clock_utime) {
  Stream& stream = streams_[stream_id];
  Entry entry;
  entry.key =
      Key{keyframe.utime, 0, keyframe.robot, keyframe.trajectory_id, keyframe.seq, "", arrivals_++};
  entry.arrival_clock = clock_utime;
  // A trajectory's times should rise with its sequence; if they do not (bad input), its
  // watermark never goes back, so the others are not held by an old time.
  stream.watermark = stream.started ? std::max(stream.watermark, keyframe.utime) : keyframe.utime;
  stream.started = true;
  entry.input.is_keyframe = true;
  entry.input.keyframe = std::move(keyframe);
  stream.queue.push_back(std::move(entry));
  Heard(stream_id, clock_utime);
  stats_.peak_held = std::max(stats_.peak_held, static_cast<int64_t>(held()));
}

void CanonicalInputOrder::AddEncounter(Encounter encounter, int64_t clock_utime) {
  Entry entry;
  entry.key = Key{encounter.utime,    1,
                  encounter.observer, encounter.observer_trajectory_id,
                  encounter.seq,      encounter.observed,
                  arrivals_++};
  entry.arrival_clock = clock_utime;
  if (encounter.seq >= 0) {
    EncounterStream& stream =
        encounter_streams_[{encounter.observer, encounter.observer_trajectory_id}];
    if (encounter.seq >= stream.next_seq) {
      if (!stream.HasGap() && encounter.seq > stream.next_seq) stream.gap_since = clock_utime;
      stream.above.emplace(encounter.seq, encounter.utime);
      while (!stream.above.empty() && stream.above.begin()->first == stream.next_seq) {
        stream.last_utime = std::max(stream.last_utime, stream.above.begin()->second);
        stream.above.erase(stream.above.begin());
        ++stream.next_seq;
      }
    }
  }
  entry.input.is_keyframe = false;
  entry.input.encounter = std::move(encounter);
  const Key key = entry.key;
  encounters_.emplace(key, std::move(entry));
  stats_.peak_held = std::max(stats_.peak_held, static_cast<int64_t>(held()));
}

void CanonicalInputOrder::ExpectEncounters(const std::string& observer, int64_t trajectory_id,
                                           int32_t count, int64_t clock_utime) {
  EncounterStream& stream = encounter_streams_[{observer, trajectory_id}];
  if (count <= stream.expected) return;
  if (!stream.HasGap() && count > stream.next_seq) stream.gap_since = clock_utime;
  stream.expected = count;
}

void CanonicalInputOrder::Heard(TrajectoryId stream_id, int64_t clock_utime) {
  Stream& stream = streams_[stream_id];
  stream.last_heard = std::max(stream.last_heard, clock_utime);
  stream.silent = false;
}

CanonicalInputOrder::Head CanonicalInputOrder::Smallest() {
  Head head;
  if (!encounters_.empty()) head.entry = &encounters_.begin()->second;
  for (auto& [id, stream] : streams_) {
    if (stream.queue.empty()) continue;
    // The arrival counter makes keys unique: no tie between streams.
    if (head.entry == nullptr || stream.queue.front().key < head.entry->key) {
      head.entry = &stream.queue.front();
      head.stream = &stream;
    }
  }
  return head;
}

OrderedInput CanonicalInputOrder::Take(const Head& head) {
  // Late: it sorts before an input already released. The arrival counter is left out of
  // the comparison (it only breaks ties between identical keys).
  const auto without_arrival = [](const Key& k) {
    return std::make_tuple(std::get<0>(k), std::get<1>(k), std::get<2>(k), std::get<3>(k),
                           std::get<4>(k), std::get<5>(k));
  };
  if (last_released_ && without_arrival(head.entry->key) < without_arrival(*last_released_)) {
    ++stats_.late;
  } else {
    last_released_ = head.entry->key;
  }
  ++stats_.released;
  OrderedInput input;
  if (head.stream != nullptr) {
    input = std::move(head.stream->queue.front().input);
    head.stream->queue.pop_front();
  } else {
    input = std::move(encounters_.begin()->second.input);
    encounters_.erase(encounters_.begin());
  }
  return input;
}

std::optional<OrderedInput> CanonicalInputOrder::Next(int64_t now_utime, bool settle,
                                                      std::vector<TrajectoryId>* silenced) {
  const Head head = Smallest();
  if (head.entry == nullptr) return std::nullopt;
  if (settle &&
      static_cast<double>(now_utime - head.entry->arrival_clock) < 1e6 * options_.settle_s) {
    return std::nullopt;
  }
  const int64_t t = std::get<0>(head.entry->key);
  bool held_back = false;
  for (auto& [id, stream] : streams_) {
    // A stream with inputs waiting sorts them after the head already.
    if (!stream.queue.empty() || (stream.started && stream.watermark >= t) || stream.silent) {
      continue;
    }
    if (static_cast<double>(now_utime - stream.last_heard) > 1e6 * options_.patience_s) {
      stream.silent = true;
      ++stats_.silences;
      if (silenced != nullptr) silenced->push_back(id);
      continue;
    }
    held_back = true;
  }
  for (const auto& [name, stream] : encounter_streams_) {
    // A gap: the missing encounters come after last_utime.
    if (stream.HasGap() && t > stream.last_utime &&
        static_cast<double>(now_utime - stream.gap_since) <= 1e6 * options_.patience_s) {
      held_back = true;
    }
  }
  if (held_back) return std::nullopt;
  return Take(head);
}

void CanonicalInputOrder::ResumeAt(int64_t clock_utime) {
  for (auto& [id, stream] : streams_) {
    if (!stream.silent) stream.last_heard = std::max(stream.last_heard, clock_utime);
    // What waits settles again from the restart: the agents hear the new server's
    // acknowledgements and resend what its predecessor lacked (an encounter sent while it
    // was down, which no later one reveals) before the inputs after it go out.
    for (Entry& entry : stream.queue) {
      entry.arrival_clock = std::max(entry.arrival_clock, clock_utime);
    }
  }
  for (auto& [key, entry] : encounters_) {
    entry.arrival_clock = std::max(entry.arrival_clock, clock_utime);
  }
  for (auto& [name, stream] : encounter_streams_) {
    if (stream.HasGap()) stream.gap_since = std::max(stream.gap_since, clock_utime);
  }
}

std::optional<OrderedInput> CanonicalInputOrder::NextAtEnd() {
  const Head head = Smallest();
  if (head.entry == nullptr) return std::nullopt;
  return Take(head);
}

size_t CanonicalInputOrder::held() const {
  size_t n = encounters_.size();
  for (const auto& [id, stream] : streams_) n += stream.queue.size();
  return n;
}

}  // namespace anchormap
