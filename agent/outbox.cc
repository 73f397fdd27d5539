#include "agent/outbox.h"

#include <algorithm>
#include <string>

namespace anchormap {

void Outbox::Erase(std::map<int32_t, Entry>* stream, std::map<int32_t, Entry>::iterator it) {
  bytes_ -= it->second.bytes.size();
  stream->erase(it);
}

Status Outbox::Add(StreamKind kind, int32_t seq, std::vector<uint8_t> bytes, int64_t now_utime) {
  std::map<int32_t, Entry>& stream = Stream(kind);
  if (const auto old = stream.find(seq); old != stream.end()) Erase(&stream, old);
  Entry entry;
  entry.kind = kind;
  entry.seq = seq;
  entry.bytes = std::move(bytes);
  entry.last_sent_utime = now_utime;
  bytes_ += entry.bytes.size();
  stream.emplace(seq, std::move(entry));
  ++stats_.added;
  int64_t dropped = 0;
  // Past the bound: the oldest keyframes go first (large, and a bridged gap replaces
  // them); encounters (small, irreplaceable) only when no other keyframe is left.
  while (static_cast<int64_t>(bytes_) > options_.max_bytes && size() > 1) {
    auto& victims = keyframes_.size() > 1 || encounters_.empty() ? keyframes_ : encounters_;
    if (victims.empty()) break;
    Erase(&victims, victims.begin());
    ++dropped;
  }
  if (dropped == 0) return Status::Ok();
  stats_.dropped += dropped;
  return Status::Error(ErrorCode::kQueueFull, "outbox over " + std::to_string(options_.max_bytes) +
                                                  " bytes: " + std::to_string(dropped) +
                                                  " unacknowledged messages dropped");
}

void Outbox::Acknowledge(int32_t keyframes_next, int32_t encounters_next) {
  for (auto* stream : {&keyframes_, &encounters_}) {
    const int32_t next = stream == &keyframes_ ? keyframes_next : encounters_next;
    while (!stream->empty() && stream->begin()->first < next) {
      Erase(stream, stream->begin());
      ++stats_.acknowledged;
    }
  }
}

std::vector<const Outbox::Entry*> Outbox::Requested(const std::vector<SeqRange>& ranges,
                                                    int64_t now_utime) {
  std::vector<const Entry*> out;
  for (const SeqRange& range : ranges) {
    std::map<int32_t, Entry>& stream = Stream(range.kind);
    int32_t found = 0;
    for (auto it = stream.lower_bound(range.first); it != stream.end() && it->first <= range.last;
         ++it) {
      it->second.last_sent_utime = now_utime;
      ++it->second.sends;
      out.push_back(&it->second);
      ++found;
    }
    const int64_t asked = static_cast<int64_t>(range.last) - range.first + 1;
    stats_.requested_but_gone += asked - found;
    stats_.resent_on_request += found;
  }
  return out;
}

std::vector<const Outbox::Entry*> Outbox::TimedOut(int64_t now_utime) {
  std::vector<Entry*> due;
  for (auto* stream : {&keyframes_, &encounters_}) {
    for (auto& [seq, entry] : *stream) {
      const double wait_s = options_.resend_timeout_s * (1 << std::min(entry.sends - 1, 2));
      if (1e-6 * static_cast<double>(now_utime - entry.last_sent_utime) >= wait_s) {
        due.push_back(&entry);
      }
    }
  }
  std::stable_sort(due.begin(), due.end(), [](const Entry* a, const Entry* b) {
    return a->last_sent_utime < b->last_sent_utime;
  });
  if (due.size() > static_cast<size_t>(options_.max_resend_per_poll)) {
    due.resize(static_cast<size_t>(options_.max_resend_per_poll));
  }
  std::vector<const Entry*> out;
  for (Entry* entry : due) {
    entry->last_sent_utime = now_utime;
    ++entry->sends;
    ++stats_.resent_on_timeout;
    out.push_back(entry);
  }
  return out;
}

}  // namespace anchormap
